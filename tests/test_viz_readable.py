"""Error maps a machinist reads: axes in mm and a colour bar in um, blocks left uncorrected drawn
apart (and flagged in the .vtp), 2.5-D programs mapped in their plane by default, no slivers on
walls, the warning on the picture, a progress line, and the in-plane map's cost.

The model has one term: EXX, the positioning error of X, 40 um per metre (``EXX_1 = 40``): the tip
stands at x + 40e-6 x, so a wall at x = X0 across X is off by 0.04 X0 um along X (hand-derived, as in
tests/test_viz_inplane.py)."""
from __future__ import annotations

import csv
import io

import numpy as np
import pytest

from mtcomp.viz import surface as viz_surface
from mtcomp.viz.surface import program_error_map, read_program_points
from test_viz_inplane import exx  # noqa: F401  (the fixture: the square and its EXX model)
from viz_parts import pocket_program, walls_program
from viz_reference import synthetic_surface_map

def _text_of(actor) -> list[str]:
    """The texts of a text actor or a corner annotation ([] for other actors)."""
    for name in ("GetInput", "GetText"):
        try:
            get = getattr(actor, name)
        except AttributeError:
            continue
        if name == "GetInput":
            return [get()] if isinstance(get(), str) else []
        return [get(i) for i in range(8) if get(i)]
    return []


def _texts(renderer) -> list[str]:
    """Every text a renderer draws."""
    return [t for a in renderer.actors.values() for t in _text_of(a)]


def _panels(smap):
    from mtcomp.viz.render import _panels
    return _panels(smap)


# ----------------------------------------------------------------------------- axes, colour bar
def test_surface_map_has_axes_in_mm_a_colour_bar_in_um_and_rms_titles():
    pytest.importorskip("pyvista")
    from mtcomp.viz.render import build_plotter, symmetric_clim
    smap = synthetic_surface_map(n=9)
    panels = _panels(smap)
    plotter = build_plotter(smap, panels, symmetric_clim(smap.dn_before_um), None, (600, 320), None)
    try:
        for k in range(2):
            cube = plotter.renderers[k].cube_axes_actor
            assert cube is not None
            assert (cube.GetXTitle(), cube.GetYTitle(), cube.GetZTitle()) == ("X (mm)", "Y (mm)",
                                                                             "Z (mm)")
            # the axes span the part: x and y from -30 to 30 mm
            np.testing.assert_allclose(cube.GetBounds()[:4], [-30, 30, -30, 30], rtol=0, atol=1e-9)
        assert len(plotter.scalar_bars) == 1
        texts = [t for r in plotter.renderers for t in _texts(r)]
        rms = [np.sqrt(np.mean(dn ** 2)) for _l, dn, _d in panels]
        assert any(f"RMS {rms[0]:.2f} um" in t and "before" in t for t in texts)
        assert any(f"RMS {rms[1]:.2f} um" in t and "after" in t for t in texts)
        assert any(t.endswith("(um)") for t in texts)              # the colour bar's unit
    finally:
        plotter.close()


def test_in_plane_map_is_a_top_view_in_mm_with_a_colour_bar_in_um(tmp_path, exx):
    from matplotlib import colormaps
    from PIL import Image

    from mtcomp.viz.render import build_contour_figure, render_error_map
    machine, fitted = exx
    smap = program_error_map(machine, fitted, tmp_path / "square.nc", normal="auto")
    assert smap.normal_kind == "in-plane"
    panels = _panels(smap)
    fig, axes, im = build_contour_figure(smap, panels, (-0.4, 0.4), None, (600, 400), None)
    ax = axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("X (mm)", "Y (mm)")
    lo, hi = ax.get_xlim()
    assert lo < -10 and hi > 10 and len(ax.get_xticks()) >= 3
    assert "RMS 0.28 um, max 0.40 um" in ax.get_title()       # sqrt(0.4^2 / 2), hand-derived
    import matplotlib.pyplot as plt
    plt.close(fig)
    res = render_error_map(smap, tmp_path / "m.png", window_size=(600, 400))
    assert res.view == "top"
    img = np.asarray(Image.open(res.png).convert("RGB"), dtype=float)
    top = np.array(colormaps["coolwarm"](1.0)[:3]) * 255
    assert np.linalg.norm(img - top, axis=2).min() < 12        # the walls at +0.4 um, and the bar


# ------------------------------------------------------------------------------- 2.5-D programs
def test_a_pocket_with_helical_entries_is_mapped_in_its_plane_by_default(tmp_path, exx):
    """Six step-downs, each entered by a helix written as G3 with Z: the reader's chords put more
    cutting points between the levels than on them, but the cutting length lies on the levels."""
    machine, fitted = exx
    (tmp_path / "pocket.nc").write_text(pocket_program(levels=6))
    prog = read_program_points(tmp_path / "pocket.nc", machine)
    tips = viz_surface.forward(machine, prog.q)[0]
    on_levels = np.isin(np.round(tips[~prog.rapid, 2], 6), -np.arange(1.0, 7.0))
    assert on_levels.mean() < 0.5                               # by points, not planar
    assert viz_surface.planar_levels(prog, machine) == 6
    smap = program_error_map(machine, fitted, prog, normal="auto")
    assert smap.normal_kind == "in-plane"
    # the walls at x = 70 and x = 130 (pocket centred on x = 100): 0.04 * x um along X
    seg = smap.segments
    a, b = smap.points[seg[:, 0]], smap.points[seg[:, 1]]
    for x0 in (70.0, 130.0):
        on = (np.abs(a[:, 0] - x0) < 1e-6) & (np.abs(b[:, 0] - x0) < 1e-6)
        assert on.sum() >= 6                                    # the wall on every level
        dn = smap.dn_before_um[seg[on]]
        np.testing.assert_allclose(np.abs(dn), 0.04 * x0, rtol=0, atol=1e-9)


def test_a_real_profile_in_34_step_downs_is_mapped_in_its_plane(exx):
    """CamBam's electric turtle (tests/data/gcode_corpus): a profile and small features cut in
    0.1 mm steps down to 3.4 mm, on 34 levels. Its surface map was flat and all grey."""
    from pathlib import Path
    machine, fitted = exx
    path = Path(__file__).parent / "data" / "gcode_corpus" / "ugs_electric_turtle.nc"
    # a program streamed to grbl by Universal Gcode Sender: grbl runs on after its M30s (the
    # last level comes after one); read by the other controllers' rules it ends at the first
    prog = read_program_points(path, machine, dialect="grbl")
    assert viz_surface.planar_levels(prog, machine) == 34
    assert viz_surface.planar_levels(read_program_points(path, machine), machine) == 33
    smap = program_error_map(machine, fitted, prog, normal="auto")
    assert smap.normal_kind == "in-plane" and smap.info["levels"] == 34
    # the outer circle (radius 55.6 mm about the origin) is there, as the outermost wall
    r = np.hypot(smap.tips[:, 0], smap.tips[:, 1])
    assert r.max() == pytest.approx(55.6, abs=0.5)
    assert smap.stats()["max_before_um"] > 1.0          # the X error across the walls shows


def test_clearing_passes_are_left_out_of_the_in_plane_map(tmp_path, exx):
    machine, fitted = exx
    (tmp_path / "pocket.nc").write_text(pocket_program(levels=2))
    smap = program_error_map(machine, fitted, tmp_path / "pocket.nc", normal="in-plane")
    seg = smap.segments
    a, b = smap.points[seg[:, 0]], smap.points[seg[:, 1]]
    # raster lines along X inside the pocket at y = 50 - 14 ... 50 + 14 (stepover 2 mm, the
    # outermost ones 4 mm from the wall keep a wall: nothing cut beyond them)
    inner = (np.abs(a[:, 1] - b[:, 1]) < 1e-9) & (np.abs(a[:, 1] - 50.0) < 14.5) \
        & (np.abs(a[:, 0] - b[:, 0]) > 10.0)
    assert not inner.any()
    assert smap.info["clearing_moves"] >= 2 * 13
    # the pocket's wall is all there: y = 30 and y = 70 from x = 72 to 128 on both levels
    for y0 in (30.0, 70.0):
        on = (np.abs(a[:, 1] - y0) < 1e-6) & (np.abs(b[:, 1] - y0) < 1e-6)
        assert np.abs(b[on, 0] - a[on, 0]).sum() == pytest.approx(2 * 56.0, rel=0, abs=1e-6)


# ------------------------------------------------------------------------------------- walls
def _steep(points, triangles, max_deg=80.0):
    a, b, c = (points[triangles[:, i]] for i in range(3))
    fn = np.cross(b - a, c - a)
    cos = np.abs(fn[:, 2]) / np.maximum(np.linalg.norm(fn, axis=1), 1e-300)
    return cos < np.cos(np.radians(max_deg))


def test_walls_have_no_slivers(tmp_path, exx):
    machine, fitted = exx
    (tmp_path / "walls.nc").write_text(walls_program())
    prog = read_program_points(tmp_path / "walls.nc", machine)
    # the surface as seen from above: the waterline levels of the wall gave vertical slivers
    tips, axes = viz_surface.forward(machine, prog.q[~prog.rapid])
    keep = viz_surface.select_surface_points(tips)
    raw = viz_surface.triangulate_xy(tips[keep])
    assert _steep(tips[keep], raw).sum() > 100                  # what the map used to draw
    smap = program_error_map(machine, fitted, prog, normal="surface")
    assert not _steep(smap.tips, smap.triangles).any()
    assert smap.info["steep_triangles"] == _steep(tips[keep], raw).sum()
    # by default (a 2.5-D program) the walls are bands up the tool axis, level to level (they
    # were horizontal fins, one per level: the comb): every triangle stands upright
    smap = program_error_map(machine, fitted, prog, normal="auto")
    assert smap.normal_kind == "in-plane"
    p, t = smap.points, smap.triangles
    a, b, c = (p[t[:, i]] for i in range(3))
    fn = np.cross(b - a, c - a)
    np.testing.assert_allclose(fn[:, 2] / np.linalg.norm(fn, axis=1), 0.0, rtol=0, atol=1e-9)
    # the boss's walls read as one wall: the band of a level reaches the level above
    x_wall = (np.abs(smap.tips[:, 0] - 85.0) < 1e-6) & (np.abs(smap.normals[:, 0]) > 0.99)
    heights = np.unique(np.round(p[x_wall, 2], 6))
    # ... and the top face's edge (z = 0), with no level above, a band of 1.5 % of the extent
    # (the floor spans 75 .. 125 mm: 0.75 mm)
    np.testing.assert_allclose(heights, np.append(-np.arange(0, 9)[::-1] * 0.5, 0.75), rtol=0,
                               atol=1e-9)


# ---------------------------------------------------------------------------- uncorrected blocks
def test_blocks_outside_the_data_are_flagged_in_the_vtp_and_drawn_grey(tmp_path, exx):
    pv = pytest.importorskip("pyvista")
    from mtcomp.viz.render import render_error_map
    machine, fitted = exx
    fitted.support = {"X": (-20.0, 0.0)}                         # the data reached x <= 0 only
    smap = program_error_map(machine, fitted, tmp_path / "square.nc", normal="in-plane")
    assert smap.status_source == "planner"
    np.testing.assert_array_equal(smap.status, np.where(smap.tips[:, 0] > 1e-6, 2, 0))
    res = render_error_map(smap, tmp_path / "m.png", window_size=(500, 300), backend="pyvista")
    back = pv.read(res.vtp)
    np.testing.assert_array_equal(back.point_data["uncorrected_reason"], smap.status)
    cells = back.cell_data["uncorrected"]
    np.testing.assert_array_equal(cells, np.any(smap.status[smap.triangles] > 0, axis=1))
    assert 0 < cells.sum() < cells.size


def test_surface_plotter_draws_uncorrected_cells_grey_with_a_legend(tmp_path, exx):
    pv = pytest.importorskip("pyvista")
    from mtcomp.viz.render import UNCORRECTED_COLOUR, build_plotter, symmetric_clim
    smap = synthetic_surface_map(n=9)
    smap.status = np.where(smap.tips[:, 0] > 0, 2, 0).astype(np.int8)
    smap.status_source = "planner"
    plotter = build_plotter(smap, _panels(smap), symmetric_clim(smap.dn_before_um), None,
                            (600, 320), None)
    try:
        import matplotlib.colors as mcolors
        grey = np.array(mcolors.to_rgb(UNCORRECTED_COLOUR))
        actors = list(plotter.renderers[0].actors.values())
        greys = [a for a in actors if isinstance(a, pv.Actor) and a.mapper is not None
                 and not a.mapper.scalar_visibility
                 and np.allclose(a.prop.color.float_rgb, grey, atol=1e-3)]
        assert len(greys) == 1
        assert greys[0].mapper.dataset.n_cells == np.count_nonzero(
            np.any(smap.status[smap.triangles] > 0, axis=1))
        legend = _text_of(plotter.renderers[0].actors["legend"])[0]
        assert "outside the region the model's data reached" in legend.replace("\n", " ")
    finally:
        plotter.close()


def test_report_marks_the_blocks_it_left_uncorrected(tmp_path, exx):
    from mtcomp.cli import main
    machine, fitted = exx
    assert main(["compensate", "xfyz", str(tmp_path / "model.json"), str(tmp_path / "square.nc"),
                 "-o", str(tmp_path / "c.nc"), "--report", str(tmp_path / "r.csv"),
                 "--quiet"]) == 0
    rows = list(csv.DictReader(io.StringIO((tmp_path / "r.csv").read_text())))
    # the block of line 5 (Y10): say the model was unsure there
    for r in rows:
        if r["line"] == "5" and r["inserted"] == "0":
            r["corrected"], r["uncertain"] = "0", "1"
    with open(tmp_path / "r2.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    smap = program_error_map(machine, fitted, tmp_path / "square.nc", report=tmp_path / "r2.csv",
                             normal="in-plane")
    assert smap.status_source == "report"
    np.testing.assert_array_equal(smap.status, np.where(smap.line == 5, 3, 0))


# ------------------------------------------------------------------------------ the warning
def test_the_warning_is_on_the_map(tmp_path, exx):
    pytest.importorskip("pyvista")
    from mtcomp.viz.render import build_plotter, symmetric_clim
    machine, fitted = exx
    (tmp_path / "pocket.nc").write_text(pocket_program(levels=3))
    smap = program_error_map(machine, fitted, tmp_path / "pocket.nc", normal="surface")
    assert len(smap.notes) == 1 and "tool axis" in smap.notes[0]
    plotter = build_plotter(smap, _panels(smap), symmetric_clim(smap.dn_before_um), None,
                            (600, 320), None)
    try:
        text = _text_of(plotter.renderers[0].actors["notes"])[0]
        assert text.startswith("warning:") and "--normal in-plane" in text.replace("\n", " ")
    finally:
        plotter.close()


# ------------------------------------------------------------------------------ progress, cost
def test_progress_lines_only_for_a_slow_render():
    from mtcomp.commands.render import Progress
    now = [0.0]
    out = io.StringIO()
    p = Progress(out, quiet_s=2.0, clock=lambda: now[0])
    p("reading")
    now[0] = 1.0
    p("contour")
    assert out.getvalue() == ""
    now[0] = 5.0
    p("drawing")
    now[0] = 7.5
    p.done()
    assert out.getvalue().splitlines() == ["mtcomp render: 5.0 s: contour done; drawing ...",
                                           "mtcomp render: 7.5 s: drawing done"]
    quiet = io.StringIO()
    p = Progress(quiet, quiet_s=2.0, clock=lambda: 0.5)
    p("reading")
    p.done()
    assert quiet.getvalue() == ""


def test_in_plane_map_evaluates_each_tool_point_once_and_merges_chords(tmp_path, exx, monkeypatch):
    """A 50 mm wall written as 10,000 G1 moves of 5 um (a CAM's output at a tight tolerance): the
    map draws segments of at least 1/1000 of the extent (50 um) and evaluates the model once per
    distinct end: about 1,000 points, not 4 per move (40,000)."""
    machine, fitted = exx
    xs = np.linspace(0.0, 50.0, 10001)
    text = "G21 G90\nG0 X0 Y0 Z5\nG1 Z-1 F300\n" + "".join(f"G1 X{x:.4f} Y0\n" for x in xs[1:]) \
        + "G0 Z5\nM30\n"
    (tmp_path / "wall.nc").write_text(text)
    calls = []
    real = viz_surface.predicted_points

    def counting(fitted_, q, *a, **k):
        calls.append(q.shape[0])
        return real(fitted_, q, *a, **k)
    monkeypatch.setattr(viz_surface, "predicted_points", counting)
    smap = program_error_map(machine, fitted, tmp_path / "wall.nc", normal="in-plane")
    assert calls == [len(np.unique(smap.line))]
    assert 900 <= calls[0] <= 1002
    # the values are the model's at those ends: the wall along X has no error across it (Y)
    np.testing.assert_allclose(smap.dn_before_um, 0.0, rtol=0, atol=1e-12)
    # segments of 50 um, give or take a move (5 um)
    assert np.all(np.diff(np.unique(np.round(smap.tips[:, 0], 6))) >= 0.045 - 1e-9)
