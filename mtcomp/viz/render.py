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
                     "in-plane": "deviation across the contour, in its plane (um)",
                     "holes": "hole position error across the tool axis (um)",
                     "path": "deviation across the path (um)"}
#: sequential colour map of a hole or path map (the size of a deviation is >= 0)
HOLE_CMAP = "viridis"
#: map kinds that show the size of a deviation (>= 0), not a signed component
SIZE_KINDS = ("holes", "path")
DEFAULT_WINDOW = (1400, 700)
MAX_GLYPHS = 600
#: whether prepare_offscreen chose EGL (so a failed render may retry without it)
_EGL_SET_BY_US = [False]


@dataclass
class RenderResult:
    """What :func:`render_error_map` wrote. clim : (lo, hi) um, the colour scale of both panels.
    view : '3-D' (pyvista's perspective, or matplotlib's top view of a surface as the fallback) or
    'top' (an in-plane or hole map: the contour or the holes seen along the tool axis)."""

    png: Path
    vtp: Path | None
    backend: str
    clim: tuple[float, float]
    stats: dict = field(default_factory=dict)
    view: str = "3-D"


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
    cells = None
    if smap.triangles.shape[0]:
        cells = smap.triangles
        faces = np.hstack([np.full((smap.triangles.shape[0], 1), 3), smap.triangles]).ravel()
        poly = pv.PolyData(np.ascontiguousarray(smap.points, dtype=float), faces)
    elif smap.normal_kind == "path" and smap.segments is not None and smap.segments.shape[0]:
        cells = smap.segments       # a path in space: its lines
        lines = np.hstack([np.full((cells.shape[0], 1), 2), cells]).ravel()
        poly = pv.PolyData(np.ascontiguousarray(smap.points, dtype=float), lines=lines)
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
    if smap.status is not None:
        status = np.asarray(smap.status, np.int8)
        poly.point_data["uncorrected_reason"] = status
        poly.point_data["uncorrected"] = (status > 0).astype(np.int8)
        if cells is not None:
            poly.cell_data["uncorrected"] = np.any(status[cells] > 0, axis=1).astype(np.int8)
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
    ext = ext if ext > 0 else 10.0          # one point (one hole): arrows on a 10 mm scale
    devs = [smap.dev_before] + ([smap.dev_after] if smap.dev_after is not None else [])
    if smap.normal_kind == "holes":         # the arrows show the error across the tool axis
        devs = [d - np.einsum("ij,ij->i", d, smap.normals)[:, None] * smap.normals for d in devs]
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
    if smap.normal_kind in SIZE_KINDS:         # the size of a deviation: from 0
        clim = (0.0, clim[1])
    if smap.normal_kind == "holes":             # its direction always drawn (arrows)
        build_holes_figure_and_save(smap, panels, out_png, clim, _glyph_scale(smap, glyph_scale),
                                    window_size, title)
        vtp_path = write_vtp(smap, out_png.with_suffix(".vtp")) if vtp else None
        return RenderResult(out_png, vtp_path, "matplotlib", clim, smap.stats(), "top")
    scale = _glyph_scale(smap, glyph_scale) if glyphs else None
    used = None
    if smap.normal_kind == "in-plane" and smap.segments is not None and backend != "pyvista":
        # a contour reads best from above, to scale, in mm: its walls are lines, not bands
        build_contour_figure_and_save(smap, panels, out_png, clim, scale, window_size, title)
        vtp_path = write_vtp(smap, out_png.with_suffix(".vtp")) if vtp else None
        return RenderResult(out_png, vtp_path, "matplotlib", clim, smap.stats(), "top")
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


#: colour of the blocks left uncorrected (they are drawn apart, off the colour scale)
UNCORRECTED_COLOUR = "#9a9a9a"
#: text colour of the warnings drawn on the map
NOTE_COLOUR = "#b00000"


def uncorrected_legend(smap: SurfaceMap) -> list[str]:
    """One legend line per reason present among the map's uncorrected points, with their count."""
    from .surface import STATUS_REASONS
    if smap.status is None:
        return []
    status = np.asarray(smap.status)
    how = "" if smap.status_source == "report" else ", by the planner's rules"
    out = []
    for code, why in STATUS_REASONS.items():
        k = int(np.count_nonzero(status == code))
        if k:
            out.append(f"not corrected: {why} ({k} points{how})")
    return out


def map_notes(smap: SurfaceMap) -> list[str]:
    """The warnings drawn on the map (and printed by the command)."""
    return [f"warning: {n}" for n in smap.notes]


def build_plotter(smap, panels, clim, scale, window_size, title):
    """The pyvista Plotter of the map, not yet rendered (tests look at its actors): per panel the
    surface coloured by dn (um) with its axes in mm (cube axes, ticks), the uncorrected cells grey
    with their points marked and a legend saying why; a colour bar in um under the panels; the
    warnings of the map under it."""
    pv = _pyvista()
    poly = to_polydata(smap)
    n = len(panels)
    # text sized to the panel: a title line of ~28 characters fits its width
    font = int(np.clip(window_size[0] / n / 60.0, 6, 12))
    plotter = pv.Plotter(off_screen=True, shape=(2, n), row_weights=[1.0, 0.22],
                         groups=[(1, np.s_[:])], border=False, window_size=list(window_size))
    plotter.set_background("white")
    rng = np.random.default_rng(0)
    glyph_idx = None
    if scale is not None and smap.points.shape[0] > MAX_GLYPHS:
        glyph_idx = np.sort(rng.choice(smap.points.shape[0], MAX_GLYPHS, replace=False))
    legend = uncorrected_legend(smap)
    mapper = None
    for k, (label, dn, dev) in enumerate(panels):
        plotter.subplot(0, k)
        mesh = poly.copy()
        mesh.point_data["dn_um"] = dn
        drawn = _add_surface(plotter, mesh, smap, clim, rng)
        mapper = drawn if drawn is not None else mapper
        if mapper is None:      # every block uncorrected: the colour bar still needs the scale
            stub = pv.PolyData(np.ascontiguousarray(smap.points[:1], dtype=float))
            stub.point_data["dn_um"] = np.zeros(1)
            mapper = plotter.add_mesh(stub, scalars="dn_um", cmap=_cmap(smap), clim=clim, opacity=0.0,
                                      show_scalar_bar=False).mapper
        text = panel_title(label, dn)
        if k == 0 and title:
            text = f"{title}\n{text}"
        plotter.add_text(text, position="upper_edge", font_size=font, color="black")
        if scale is not None:
            _add_arrows(pv, plotter, smap, dev, scale, glyph_idx, font)
        # the part's coordinates: axes in mm with ticks, on the outer edges of its bounding box
        plotter.show_bounds(mesh=mesh, xtitle="X (mm)", ytitle="Y (mm)", ztitle="Z (mm)",
                            color="black", font_size=max(font - 2, 6), location="outer",
                            ticks="outside", n_xlabels=4, n_ylabels=4, n_zlabels=3, fmt="%.0f",
                            use_2d=False, minor_ticks=False)
        plotter.view_vector((-0.5, -1.0, 0.75), viewup=(0, 0, 1))
        # room under the part for the legend and the warnings, when there are any
        plotter.camera.zoom(0.8 if (legend or smap.notes) else 0.95)
    plotter.subplot(1, 0)
    plotter.add_scalar_bar(title=" ", mapper=mapper, vertical=False, position_x=0.25,
                           position_y=0.5, width=0.5, height=0.45, color="black",
                           label_font_size=max(font + 1, 8), n_labels=7, fmt="%.2f")
    plotter.add_text(SCALAR_BAR_TITLES[smap.normal_kind], position="lower_edge",
                     font_size=max(font - 1, 6), color="black")
    _add_legend_and_notes(plotter, smap, legend, window_size[0] / n, font)
    if n > 1:
        plotter.link_views()
    return plotter


def _cmap(smap) -> str:
    """The colour map of the map's kind: sequential for a size (>= 0), diverging for a component."""
    return HOLE_CMAP if smap.normal_kind in SIZE_KINDS else CMAP


def _add_surface(plotter, mesh, smap, clim, rng):
    """Draw one panel's ``mesh``: the corrected part coloured by dn (um), the uncorrected part grey
    with its points marked (at most MAX_GLYPHS / 3, drawn with ``rng``). Returns the colour mapper
    of the coloured part, or None when every block is uncorrected."""
    bad = smap.uncorrected
    lines = smap.normal_kind == "path" and "uncorrected" in mesh.cell_data and mesh.n_lines > 0
    surface = bool(smap.triangles.shape[0])
    cells = surface or lines
    style = ({} if surface else {"line_width": 4, "render_lines_as_tubes": True} if lines else
             {"style": "points", "point_size": 6, "render_points_as_spheres": True})
    cmap = _cmap(smap)
    mapper = None
    good = mesh
    if bad.any() and cells:
        good = mesh.extract_cells(np.flatnonzero(mesh.cell_data["uncorrected"] == 0))
    elif bad.any():
        good = mesh.extract_points(np.flatnonzero(~bad), adjacent_cells=False)
    if good.n_points:
        actor = plotter.add_mesh(good, scalars="dn_um", cmap=cmap, clim=clim,
                                 show_scalar_bar=False, ambient=0.45, diffuse=0.6,
                                 specular=0.0, smooth_shading=surface, **style)
        mapper = actor.mapper
    if bad.any():
        grey = (mesh.extract_cells(np.flatnonzero(mesh.cell_data["uncorrected"] == 1))
                if cells else mesh.extract_points(np.flatnonzero(bad), adjacent_cells=False))
        if grey.n_points:
            # grey, and hatched by its own edges where the cells are few enough to show them
            # (the edges' width for a surface; a path's lines keep their own width)
            plotter.add_mesh(grey, color=UNCORRECTED_COLOUR, ambient=0.6, diffuse=0.4,
                             show_edges=surface and grey.n_cells <= 2000,
                             **{"edge_color": "#6e6e6e", "line_width": 0.5, **style})
        marks = smap.points[bad]
        if marks.shape[0] > MAX_GLYPHS // 3:
            marks = marks[np.sort(rng.choice(marks.shape[0], MAX_GLYPHS // 3, replace=False))]
        plotter.add_points(np.ascontiguousarray(marks), color="black", point_size=3,
                           render_points_as_spheres=True)
    return mapper


def _add_arrows(pv, plotter, smap, dev, scale: float, glyph_idx, font: int) -> None:
    """Arrows of the deviation ``dev`` (N, 3) mm times ``scale`` at the map's points (those of
    ``glyph_idx`` when not None), and a note saying the scale (``pv``: the pyvista module)."""
    idx = slice(None) if glyph_idx is None else glyph_idx
    pts = pv.PolyData(np.ascontiguousarray(smap.points[idx]))
    pts.point_data["vec"] = dev[idx] * scale
    arrows = pts.glyph(orient="vec", scale="vec", factor=1.0, geom=pv.Arrow())
    plotter.add_mesh(arrows, color="black")
    plotter.add_text(f"arrows: deviation x {scale:.3g}", position="lower_right",
                     font_size=max(font - 3, 5), color="black")


def _add_legend_and_notes(plotter, smap, legend: list, panel_width: float, font: int) -> None:
    """Under the first panel's part: why blocks are grey (the legend), and the map's warnings,
    wrapped to the panel's width (pixels)."""
    import textwrap
    small = max(font - 3, 6)
    width = max(int(panel_width / small * 0.95), 30)     # a character is about a font size wide
    lines = [textwrap.fill("grey, dotted: " + t, width) for t in legend]
    notes = [textwrap.fill(t, width) for t in map_notes(smap)]
    plotter.subplot(0, 0)
    if lines:
        plotter.add_text("\n".join(lines), position="lower_left", font_size=small,
                         color="#404040", name="legend")
    if notes:
        rows = sum(t.count("\n") + 1 for t in lines)
        plotter.add_text("\n".join(notes), position=(4, 4 + int(1.6 * small * rows) + (4 if rows else 0)),
                         font_size=small, color=NOTE_COLOUR, name="notes")


def _render_pyvista(smap, panels, out_png, clim, scale, window_size, title):
    plotter = build_plotter(smap, panels, clim, scale, window_size, title)
    try:
        img = plotter.screenshot(None, return_img=True)
        from PIL import Image
        with atomic_write(out_png, "wb") as f:
            Image.fromarray(np.asarray(img)).save(f, format="PNG", optimize=True)
    finally:
        plotter.close()


def _matplotlib():
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    return plt


def _finish_figure(fig, axes, im, smap, out_png, legend_handles):
    """The colour bar in um under the panels, the legend of the uncorrected blocks, the warnings;
    then the PNG, atomically."""
    plt = _matplotlib()
    if im is not None:
        fig.colorbar(im, ax=list(axes), orientation="horizontal",
                     label=SCALAR_BAR_TITLES[smap.normal_kind], shrink=0.6, aspect=40)
    if legend_handles:
        fig.legend(handles=legend_handles, loc="outside lower center", fontsize="small",
                   frameon=False)
    notes = map_notes(smap)
    if notes:
        # under the colour bar, the layout kept above it and narrower by as much on each side:
        # panels drawn to scale fill their width, so their height gives way only so (a suptitle
        # overlapped the titles of a hole map's panels)
        # wrapped to the figure's width (about 0.6 of a 10 pt character each; a note ran off both
        # sides of a 300 px map)
        import textwrap
        chars = max(20, int(fig.get_figwidth() * 72 / 6))
        text = "\n".join(textwrap.fill(n, chars) for n in notes)
        h = min(0.3, (18 * (text.count("\n") + 1) + 6) / (fig.get_figheight() * fig.dpi))
        fig.get_layout_engine().set(rect=(h, h, 1 - 2 * h, 1 - h))
        fig.text(0.5, 0.005, text, ha="center", va="bottom", color=NOTE_COLOUR, fontsize="medium")
    try:
        with atomic_write(out_png, "wb") as f:
            fig.savefig(f, dpi=fig.dpi, format="png")
    finally:
        plt.close(fig)


def _legend_handles(smap, marker):
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    lines = uncorrected_legend(smap)
    if marker:
        return [Line2D([], [], color=UNCORRECTED_COLOUR, lw=2.5, ls=(0, (2, 1)), marker="x",
                       markeredgecolor="black", label=line) for line in lines]
    return [Patch(facecolor=UNCORRECTED_COLOUR, edgecolor="black", hatch="///", label=line)
            for line in lines]


#: a top view whose extent in X and Y differ by more than this factor is drawn stretched (a
#: 950 x 20 mm part to scale is a hairline)
MAX_TO_SCALE_RATIO = 8.0


def _top_view_aspect(ax, xy: np.ndarray) -> str:
    """Draw the panel to scale, unless its extents differ by more than MAX_TO_SCALE_RATIO: then
    stretched to fill it. Returns '' or the words the title gets ('; not to scale')."""
    span = np.ptp(xy, axis=0) if xy.size else np.zeros(2)
    if span.min() > 0 and span.max() / span.min() > MAX_TO_SCALE_RATIO:
        ax.set_aspect("auto")
        return "; not to scale"
    ax.set_aspect("equal")
    return ""


def _top_view_panels(n: int, window_size):
    """(figure, n axes) side by side sharing their X and Y: maps seen along the tool axis."""
    plt = _matplotlib()
    dpi = 100
    fig, axes = plt.subplots(1, n, figsize=(window_size[0] / dpi, window_size[1] / dpi), dpi=dpi,
                             squeeze=False, constrained_layout=True, sharex=True, sharey=True)
    return fig, axes[0]


def build_contour_figure(smap, panels, clim, scale, window_size, title):
    """The matplotlib Figure of an in-plane map (tests look at it): per panel the contour seen along
    the tool axis, to scale, axes in mm; each segment drawn as a line in two halves, each coloured
    by the dn (um) of its own end (a corner keeps both walls' values); where several levels lie
    on each other, the largest |dn| is drawn on top. Blocks left uncorrected: grey, dashed,
    marked x, in a legend that says why."""
    from matplotlib.collections import LineCollection
    from matplotlib.colors import Normalize
    fig, axes = _top_view_panels(len(panels), window_size)
    seg = smap.segments
    a, b = seg[:, 0], seg[:, 1]
    pa, pb = smap.points[a, :2], smap.points[b, :2]
    half = np.concatenate([np.stack([pa, 0.5 * (pa + pb)], axis=1),
                           np.stack([0.5 * (pa + pb), pb], axis=1)])
    end = np.concatenate([a, b])
    bad = smap.uncorrected[end]
    norm = Normalize(clim[0], clim[1])
    width = float(np.clip(window_size[0] / len(panels) / 250.0, 1.2, 3.5))
    levels = smap.info.get("levels", 0)
    im = None
    for ax, (label, dn, dev) in zip(axes, panels):
        value = dn[end]
        order = np.argsort(np.abs(value[~bad]))
        good = np.flatnonzero(~bad)[order]
        lc = LineCollection(half[good], array=value[good], cmap=CMAP, norm=norm, linewidths=width,
                            capstyle="round")
        ax.add_collection(lc)
        im = lc
        if bad.any():
            ax.add_collection(LineCollection(half[bad], colors=UNCORRECTED_COLOUR,
                                             linewidths=width, linestyles=(0, (2, 1))))
            marks = smap.points[end[bad], :2]
            step = max(1, marks.shape[0] // 300)
            ax.plot(marks[::step, 0], marks[::step, 1], "x", color="black", ms=4, mew=0.8)
        if scale is not None:
            step = max(1, smap.points.shape[0] // MAX_GLYPHS)
            ax.quiver(smap.points[::step, 0], smap.points[::step, 1], dev[::step, 0] * scale,
                      dev[::step, 1] * scale, angles="xy", scale_units="xy", scale=1.0, width=0.002)
        to_scale = _top_view_aspect(ax, smap.points[:, :2])
        ax.autoscale_view()
        ax.margins(0.04)
        ax.set_xlabel("X (mm)")
        ax.set_ylabel("Y (mm)")
        ax.grid(True, color="#dddddd", lw=0.5)
        ax.set_axisbelow(True)
        text = panel_title(label, dn) + to_scale
        if levels > 1:
            lo, hi = smap.info.get("level_range_mm") or (0.0, 0.0)
            text += f"\n{levels} levels, Z {lo:g} .. {hi:g} mm (largest |dn| on top)"
        ax.set_title(text if not (title and ax is axes[0]) else f"{title}\n{text}")
    return fig, axes, im


def build_contour_figure_and_save(smap, panels, out_png, clim, scale, window_size, title):
    fig, axes, im = build_contour_figure(smap, panels, clim, scale, window_size, title)
    _finish_figure(fig, axes, im, smap, out_png, _legend_handles(smap, marker=True))


def build_holes_figure(smap, panels, clim, scale, window_size, title):
    """The matplotlib Figure of a hole map (tests look at it): per panel the holes seen along the
    tool axis at their programmed positions, axes in mm, each a disc coloured by the size of its
    position error across the tool axis (um) with an arrow showing that error's direction,
    exaggerated ``scale`` times (said in the title); the depth error (along the tool axis) in the
    title. Holes left uncorrected: grey, marked x, in a legend that says why."""
    fig, axes = _top_view_panels(len(panels), window_size)
    xy = smap.tips[:, :2]
    bad = smap.uncorrected
    im = None
    for ax, (label, dn, dev) in zip(axes, panels):
        across = dev - np.einsum("ij,ij->i", dev, smap.normals)[:, None] * smap.normals
        im = ax.scatter(xy[~bad, 0], xy[~bad, 1], c=dn[~bad], s=60, cmap=HOLE_CMAP, vmin=clim[0],
                        vmax=clim[1], edgecolors="black", linewidths=0.4, zorder=2)
        if bad.any():
            ax.scatter(xy[bad, 0], xy[bad, 1], s=60, c=UNCORRECTED_COLOUR, edgecolors="black",
                       linewidths=0.4, zorder=2)
            ax.plot(xy[bad, 0], xy[bad, 1], "x", color="black", ms=5, mew=0.9, zorder=3)
        step = max(1, xy.shape[0] // MAX_GLYPHS)
        ax.quiver(xy[::step, 0], xy[::step, 1], across[::step, 0] * scale, across[::step, 1] * scale,
                  angles="xy", scale_units="xy", scale=1.0, width=0.003, color="#c00000", zorder=4)
        ax.update_datalim(xy + across[:, :2] * scale)      # the arrows inside the panel
        to_scale = _top_view_aspect(ax, xy)
        ax.autoscale_view()
        ax.margins(0.08)
        ax.set_xlabel("X (mm)")
        ax.set_ylabel("Y (mm)")
        ax.grid(True, color="#dddddd", lw=0.5)
        ax.set_axisbelow(True)
        depth = smap.depth_um(dev)
        text = (panel_title(label, dn).replace("RMS", "position error RMS")
                + f"\ndepth error RMS {float(np.sqrt(np.mean(depth ** 2))) if depth.size else 0.0:.2f}"
                f" um; arrows x{scale:.3g}{to_scale}")
        ax.set_title(text if not (title and ax is axes[0]) else f"{title}\n{text}")
    return fig, axes, im


def build_holes_figure_and_save(smap, panels, out_png, clim, scale, window_size, title):
    fig, axes, im = build_holes_figure(smap, panels, clim, scale, window_size, title)
    _finish_figure(fig, axes, im, smap, out_png, _legend_handles(smap, marker=True))


def build_surface_figure(smap, panels, clim, scale, window_size, title):
    """The matplotlib Figure of a surface map (when VTK cannot render): a top view, ``tripcolor``,
    axes in mm, the uncorrected triangles grey and hatched."""
    from matplotlib.collections import PolyCollection
    from matplotlib.tri import Triangulation
    plt = _matplotlib()
    dpi = 100
    fig, axes = plt.subplots(1, len(panels), figsize=(window_size[0] / dpi, window_size[1] / dpi),
                             dpi=dpi, squeeze=False, constrained_layout=True)
    axes = axes[0]
    tri = (Triangulation(smap.points[:, 0], smap.points[:, 1], smap.triangles)
           if smap.triangles.shape[0] else None)
    bad = smap.uncorrected
    bad_tri = (np.any(bad[smap.triangles], axis=1) if tri is not None
               else np.zeros(0, bool))
    im = None
    names = "XY"
    for ax, (label, dn, dev) in zip(axes, panels):
        if tri is None:         # a path, not a surface: its points, seen along the axis it spans
            span = np.ptp(smap.points, axis=0) if smap.points.size else np.zeros(3)
            u, v = (0, 1) if span[1] > 0 or span[2] == 0 else (0, 2)
            names = "XYZ"[u] + "XYZ"[v]
            im = ax.scatter(smap.points[~bad, u], smap.points[~bad, v], c=dn[~bad], s=8, cmap=_cmap(smap),
                            vmin=clim[0], vmax=clim[1])
            if bad.any():
                ax.scatter(smap.points[bad, u], smap.points[bad, v], c=UNCORRECTED_COLOUR, s=10,
                           marker="x")
        else:
            im = ax.tripcolor(tri, dn, shading="gouraud", cmap=CMAP, vmin=clim[0], vmax=clim[1])
            if bad_tri.any():
                verts = smap.points[smap.triangles[bad_tri]][:, :, :2]
                ax.add_collection(PolyCollection(verts, facecolors=UNCORRECTED_COLOUR,
                                                 edgecolors="none"))
                ax.add_collection(PolyCollection(verts, facecolors="none", edgecolors="black",
                                                 hatch="///", linewidths=0.0))
        if scale is not None:
            step = max(1, smap.points.shape[0] // MAX_GLYPHS)
            ax.quiver(smap.points[::step, 0], smap.points[::step, 1], dev[::step, 0] * scale,
                      dev[::step, 1] * scale, angles="xy", scale_units="xy", scale=1.0, width=0.002)
        ax.set_aspect("equal")
        ax.set_xlabel(f"{names[0]} (mm)")
        ax.set_ylabel(f"{names[1]} (mm)")
        ax.set_title(panel_title(label, dn) if not (title and ax is axes[0])
                     else f"{title}\n{panel_title(label, dn)}")
    return fig, axes, im


def _render_matplotlib(smap, panels, out_png, clim, scale, window_size, title):
    fig, axes, im = build_surface_figure(smap, panels, clim, scale, window_size, title)
    _finish_figure(fig, axes, im, smap, out_png, _legend_handles(smap, marker=False))
