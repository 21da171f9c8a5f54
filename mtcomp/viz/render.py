"""Drawing a :class:`~mtcomp.viz.surface.SurfaceMap`: PNG (pyvista, off-screen) and .vtp (ParaView).

pyvista is imported here, inside the functions, never when mtcomp is imported. Rendering needs no
display: the plotter is created with ``off_screen=True``; on Linux without ``DISPLAY`` the VTK wheels
render through EGL (Mesa's surfaceless platform works with no GPU), and VTK is told so up front
(``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow``) so that it does not first try an X server. If VTK
cannot render at all, the PNG is drawn with matplotlib's ``tripcolor`` instead (top view, same colour
scale, same titles) and the .vtp is written all the same. ``RenderResult.backend`` says which ran.
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_write
from .surface import SurfaceMap

#: diverging colour map: blue = tool dug in (dn < 0), red = material left (dn > 0)
CMAP = "coolwarm"
SCALAR_BAR_TITLE = "deviation along surface normal (um)"
#: the scale bar's title per SurfaceMap.normal_kind
SCALAR_BAR_TITLES = {"surface": SCALAR_BAR_TITLE,
                     "in-plane": "deviation across the contour, in its plane (um)"}
DEFAULT_WINDOW = (1400, 700)
MAX_GLYPHS = 600
#: whether prepare_offscreen chose EGL (so a failed render may retry without it)
_EGL_SET_BY_US = [False]


@dataclass
class RenderResult:
    """What :func:`render_error_map` wrote. clim : (lo, hi) um, the colour scale of both panels."""

    png: Path
    vtp: Path | None
    backend: str
    clim: tuple[float, float]
    stats: dict = field(default_factory=dict)


def prepare_offscreen() -> None:
    """Make VTK render without a display: on Linux with no X/Wayland display, select EGL."""
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY") \
            and not os.environ.get("WAYLAND_DISPLAY") and "VTK_DEFAULT_OPENGL_WINDOW" not in os.environ:
        os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = "vtkEGLRenderWindow"
        _EGL_SET_BY_US[0] = True


def _pyvista():
    prepare_offscreen()
    import pyvista as pv
    pv.OFF_SCREEN = True
    return pv


def symmetric_clim(*fields: np.ndarray | None) -> tuple[float, float]:
    """(-m, m) um with m the largest |value| of all fields (at least 1e-3 um)."""
    m = 0.0
    for f in fields:
        if f is not None and np.size(f):
            m = max(m, float(np.max(np.abs(f))))
    m = max(m, 1e-3)
    return (-m, m)


def panel_title(label: str, dn: np.ndarray) -> str:
    rms = float(np.sqrt(np.mean(dn ** 2))) if dn.size else 0.0
    mx = float(np.max(np.abs(dn))) if dn.size else 0.0
    return f"{label}\nRMS {rms:.2f} um, max {mx:.2f} um"


#: what a map shows -> (title of the single panel, of the before panel, of the after panel)
PANEL_TITLES = {
    "model": ("Model prediction", "Model prediction: before", "Model prediction: after"),
    "truth": ("Part as cut (truth)", "As cut (truth): uncompensated", "As cut (truth): compensated"),
}


def _panels(smap: SurfaceMap, shows: str = "model"):
    single, before, after = PANEL_TITLES[shows]
    panels = [(before if smap.dev_after is not None else single, smap.dn_before_um, smap.dev_before)]
    if smap.dev_after is not None:
        panels.append((after, smap.dn_after_um, smap.dev_after))
    return panels


def to_polydata(smap: SurfaceMap):
    """The map as a pyvista PolyData with point arrays (um and mm as named)."""
    pv = _pyvista()
    if smap.triangles.shape[0]:
        faces = np.hstack([np.full((smap.triangles.shape[0], 1), 3), smap.triangles]).ravel()
        poly = pv.PolyData(np.ascontiguousarray(smap.points, dtype=float), faces)
    else:       # a path, not a surface: its points
        poly = pv.PolyData(np.ascontiguousarray(smap.points, dtype=float))
    poly.point_data["dn_before_um"] = smap.dn_before_um
    poly.point_data["dev_before_um"] = 1e3 * smap.dev_before
    if smap.dev_after is not None:
        poly.point_data["dn_after_um"] = smap.dn_after_um
        poly.point_data["dev_after_um"] = 1e3 * smap.dev_after
    poly.point_data["normal"] = smap.normals
    poly.point_data["nominal_tip_mm"] = smap.tips
    poly.point_data["line"] = smap.line.astype(np.int64)
    return poly


def write_vtp(smap: SurfaceMap, path) -> Path:
    """Write the map as a VTK XML PolyData file (.vtp) that ParaView opens; atomic."""
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter
    path = Path(path)
    writer = vtkXMLPolyDataWriter()
    writer.SetInputData(to_polydata(smap))
    writer.SetDataModeToBinary()
    writer.WriteToOutputStringOn()
    if not writer.Write():
        raise RuntimeError("VTK could not serialise the map")
    text = writer.GetOutputString()
    with atomic_write(path, "wb") as f:
        f.write(text.encode("latin-1") if isinstance(text, str) else bytes(text))
    return path


def _glyph_scale(smap: SurfaceMap, glyph_scale: float | None) -> float:
    if glyph_scale is not None:
        return float(glyph_scale)
    ext = np.ptp(smap.points[:, :2], axis=0).max() if smap.points.size else 1.0
    devs = [smap.dev_before] + ([smap.dev_after] if smap.dev_after is not None else [])
    big = max(float(np.max(np.linalg.norm(d, axis=1))) for d in devs) if smap.points.size else 0.0
    return 0.1 * ext / big if big > 0 else 1.0


def render_error_map(smap: SurfaceMap, out_png, *, glyphs: bool = False,
                     glyph_scale: float | None = None, clim: tuple[float, float] | None = None,
                     window_size: tuple[int, int] = DEFAULT_WINDOW, vtp: bool = True,
                     backend: str = "auto", title: str | None = None,
                     shows: str = "model") -> RenderResult:
    """Draw the map: before (and after, if the map has it) side by side, one colour scale in um.

    out_png : the PNG to write; the .vtp goes next to it with the same stem (``vtp=False``: none).
    glyphs : draw the deviation vectors as arrows, exaggerated ``glyph_scale`` times (default: the
        largest arrow is a tenth of the part's size). clim : colour range in um (default symmetric,
        the largest |dn| of both panels). backend : 'auto' (pyvista, matplotlib if VTK cannot render),
        'pyvista' or 'matplotlib'. shows : what the deviations are, said in the panel titles:
        'model' (the model's prediction) or 'truth' (the error of a part actually cut, e.g. by the
        demo's virtual machine). Both files are written atomically.
    """
    out_png = Path(out_png)
    if out_png.suffix.lower() != ".png":
        raise InputError("the map must be a .png file", out_png)
    if not out_png.resolve().parent.is_dir():
        raise InputError(f"output folder {out_png.resolve().parent} does not exist", out_png)
    if backend not in ("auto", "pyvista", "matplotlib"):
        raise ValueError(f"unknown backend {backend!r}")
    if shows not in PANEL_TITLES:
        raise ValueError(f"shows must be one of {sorted(PANEL_TITLES)}, got {shows!r}")
    panels = _panels(smap, shows)
    if clim is None:
        clim = symmetric_clim(*[p[1] for p in panels])
    clim = (float(clim[0]), float(clim[1]))
    scale = _glyph_scale(smap, glyph_scale) if glyphs else None
    used = None
    if backend in ("auto", "pyvista"):
        try:
            _render_pyvista(smap, panels, out_png, clim, scale, window_size, title)
            used = "pyvista"
        except Exception as exc:  # no OpenGL context
            if backend == "pyvista":
                raise
            first = exc
            if os.environ.get("VTK_DEFAULT_OPENGL_WINDOW") == "vtkEGLRenderWindow" \
                    and _EGL_SET_BY_US[0]:
                # EGL was our choice: let VTK pick its own off-screen window (e.g. OSMesa) once
                del os.environ["VTK_DEFAULT_OPENGL_WINDOW"]
                _EGL_SET_BY_US[0] = False
                try:
                    _render_pyvista(smap, panels, out_png, clim, scale, window_size, title)
                    used = "pyvista"
                except Exception as exc2:
                    first = exc2
            if used is None:
                sys.stderr.write(f"mtcomp: VTK could not render off-screen ({type(first).__name__}: "
                                 f"{first}); drawing the PNG with matplotlib\n")
    if used is None:
        _render_matplotlib(smap, panels, out_png, clim, scale, window_size, title)
        used = "matplotlib"
    vtp_path = None
    if vtp:
        vtp_path = write_vtp(smap, out_png.with_suffix(".vtp"))
    return RenderResult(out_png, vtp_path, used, clim, smap.stats())


def _render_pyvista(smap, panels, out_png, clim, scale, window_size, title):
    pv = _pyvista()
    poly = to_polydata(smap)
    n = len(panels)
    # text sized to the panel: a title line of ~28 characters fits its width
    font = int(np.clip(window_size[0] / n / 60.0, 6, 12))
    plotter = pv.Plotter(off_screen=True, shape=(2, n), row_weights=[1.0, 0.16],
                         groups=[(1, np.s_[:])], border=False, window_size=list(window_size))
    try:
        plotter.set_background("white")
        rng = np.random.default_rng(0)
        glyph_idx = None
        if scale is not None and smap.points.shape[0] > MAX_GLYPHS:
            glyph_idx = np.sort(rng.choice(smap.points.shape[0], MAX_GLYPHS, replace=False))
        mapper = None
        for k, (label, dn, dev) in enumerate(panels):
            plotter.subplot(0, k)
            mesh = poly.copy()
            mesh.point_data["dn_um"] = dn
            style = ({} if smap.triangles.shape[0] else
                     {"style": "points", "point_size": 6, "render_points_as_spheres": True})
            actor = plotter.add_mesh(mesh, scalars="dn_um", cmap=CMAP, clim=clim,
                                     show_scalar_bar=False, ambient=0.45, diffuse=0.6, specular=0.0,
                                     smooth_shading=True, **style)
            mapper = actor.mapper
            text = panel_title(label, dn)
            if k == 0 and title:
                text = f"{title}\n{text}"
            plotter.add_text(text, position="upper_edge", font_size=font, color="black")
            if scale is not None:
                idx = slice(None) if glyph_idx is None else glyph_idx
                pts = pv.PolyData(np.ascontiguousarray(smap.points[idx]))
                pts.point_data["vec"] = dev[idx] * scale
                arrows = pts.glyph(orient="vec", scale="vec", factor=1.0, geom=pv.Arrow())
                plotter.add_mesh(arrows, color="black")
                plotter.add_text(f"arrows: deviation x {scale:.3g}", position="lower_left",
                                 font_size=max(font - 3, 5), color="black")
            plotter.view_vector((-0.5, -1.0, 0.75), viewup=(0, 0, 1))
            plotter.camera.zoom(1.15)
        plotter.subplot(1, 0)
        plotter.add_scalar_bar(title=" ", mapper=mapper, vertical=False, position_x=0.2,
                               position_y=0.45, width=0.6, height=0.5, color="black",
                               label_font_size=max(font + 1, 8), n_labels=7, fmt="%.2f")
        plotter.add_text(SCALAR_BAR_TITLES[smap.normal_kind], position="lower_edge", font_size=max(font - 1, 6),
                         color="black")
        if n > 1:
            plotter.link_views()
        img = plotter.screenshot(None, return_img=True)
        from PIL import Image
        with atomic_write(out_png, "wb") as f:
            Image.fromarray(np.asarray(img)).save(f, format="PNG", optimize=True)
    finally:
        plotter.close()


def _render_matplotlib(smap, panels, out_png, clim, scale, window_size, title):
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation
    dpi = 100
    fig, axes = plt.subplots(1, len(panels), figsize=(window_size[0] / dpi, window_size[1] / dpi),
                             dpi=dpi, squeeze=False, constrained_layout=True)
    tri = (Triangulation(smap.points[:, 0], smap.points[:, 1], smap.triangles)
           if smap.triangles.shape[0] else None)
    im = None
    names = "XY"
    for ax, (label, dn, dev) in zip(axes[0], panels):
        if tri is None:         # a path, not a surface: its points, seen along the axis it spans
            span = np.ptp(smap.points, axis=0) if smap.points.size else np.zeros(3)
            u, v = (0, 1) if span[1] > 0 or span[2] == 0 else (0, 2)
            names = "XYZ"[u] + "XYZ"[v]
            im = ax.scatter(smap.points[:, u], smap.points[:, v], c=dn, s=8, cmap=CMAP,
                            vmin=clim[0], vmax=clim[1])
        else:
            im = ax.tripcolor(tri, dn, shading="gouraud", cmap=CMAP, vmin=clim[0], vmax=clim[1])
        if scale is not None:
            step = max(1, smap.points.shape[0] // MAX_GLYPHS)
            ax.quiver(smap.points[::step, 0], smap.points[::step, 1], dev[::step, 0] * scale,
                      dev[::step, 1] * scale, angles="xy", scale_units="xy", scale=1.0, width=0.002)
        ax.set_aspect("equal")
        ax.set_xlabel(f"{names[0]} (mm)")
        ax.set_ylabel(f"{names[1]} (mm)")
        ax.set_title(panel_title(label, dn) if not (title and ax is axes[0][0])
                     else f"{title}\n{panel_title(label, dn)}")
    fig.colorbar(im, ax=axes[0].tolist(), orientation="horizontal",
                 label=SCALAR_BAR_TITLES[smap.normal_kind],
                 shrink=0.6)
    try:
        with atomic_write(out_png, "wb") as f:
            fig.savefig(f, dpi=dpi, format="png")
    finally:
        plt.close(fig)
