"""Hole and path maps: a drilling program is mapped as its holes, where they are, coloured by each
hole's position error across the tool axis, with the depth error in the titles; a path in space that
is no surface is drawn as its lines, coloured by the deviation across the path.

The model has one term: EXX, the positioning error of X, 40 um per metre (``EXX_1 = 40``): the tip
stands at x + 40e-6 x, so a hole at x = X0 is off by 0.04 X0 um along X, and not at all in depth
(hand-derived, as in tests/test_viz_inplane.py)."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.viz.surface import program_error_map
from test_viz_inplane import exx as exx_square  # noqa: F401  (the fixture: the EXX model)

#: holes by a canned cycle: the first line names the cycle, the next ones are more holes
CYCLE = """G21 G90 G17
G0 X0 Y0 Z10
G81 X10. Y5. Z-3. R2. F100
X50. Y5.
X100. Y20.
G80
G0 Z10
M30
"""
#: the same holes plunged with G1 (no cycle)
PLUNGED = """G21 G90
G0 X0 Y0 Z10
G0 X10 Y5
G1 Z-3 F100
G0 Z2
G0 X50 Y5
G1 Z-3
G0 Z2
G0 X100 Y20
G1 Z-3
G0 Z10
M30
"""
#: a milled slot: a feed move across the tool axis, no hole
SLOT = """G21 G90
G0 X0 Y0 Z5
G1 Z-1 F100
G1 X40
G0 Z5
M30
"""
_XY = re.compile(r"X([-\d.]+)\s*Y([-\d.]+)")


@pytest.fixture()
def exx(tmp_path, exx_square):
    for name, text in (("cycle.nc", CYCLE), ("plunged.nc", PLUNGED), ("slot.nc", SLOT)):
        (tmp_path / name).write_text(text)
    return exx_square


def _holes_of(text: str) -> np.ndarray:
    """(n, 2) the holes' X Y as the program writes them (the lines that drill: the cycle's, or the
    rapid before each plunge), read here from the text."""
    lines = text.splitlines()
    if "G81" in text:
        rows = [m for ln in lines if (m := _XY.search(ln)) and not ln.startswith("G0")]
    else:
        rows = [_XY.search(lines[i - 1]) for i, ln in enumerate(lines) if ln.startswith("G1 Z")]
    return np.array([[float(m.group(1)), float(m.group(2))] for m in rows])


@pytest.mark.parametrize("name, text", [("cycle.nc", CYCLE), ("plunged.nc", PLUNGED)])
def test_a_drilling_program_maps_its_holes_with_their_position_error(tmp_path, exx, name, text):
    machine, fitted = exx
    smap = program_error_map(machine, fitted, tmp_path / name, normal="auto")
    assert smap.normal_kind == "holes"
    holes = _holes_of(text)
    np.testing.assert_allclose(smap.tips[:, :2], holes, rtol=0, atol=1e-9)
    # EXX: 0.04 um per mm of X, along X: the position error is 0.04 |x|, the depth error 0
    np.testing.assert_allclose(smap.dn_before_um, 0.04 * np.abs(holes[:, 0]), rtol=0, atol=1e-6)
    np.testing.assert_allclose(smap.depth_um(smap.dev_before), 0.0, rtol=0, atol=1e-6)
    st = smap.stats()
    np.testing.assert_allclose(st["max_before_um"], 4.0, rtol=0, atol=1e-6)
    np.testing.assert_allclose(st["rms_before_um"], np.sqrt(np.mean((0.04 * holes[:, 0]) ** 2)),
                               rtol=1e-9, atol=0)


#: the same holes pecked in three steps each with G0/G1 (grbl has no canned cycles), the last hole's
#: deepest peck not its last (a peck-back program); a fourth hole at X100 Y20 again, after another
PECKED = """G21 G90
G0 X0 Y0 Z10
G0 X10 Y5
G1 Z-1 F100
G0 Z1
G1 Z-2
G0 Z1
G1 Z-3
G0 Z2
G0 X50 Y5
G1 Z-1
G0 Z1
G1 Z-2
G0 Z1
G1 Z-3
G0 Z2
G0 X100 Y20
G1 Z-1
G0 Z1
G1 Z-3
G0 Z1
G1 Z-2
G0 Z10
G0 X0 Y0
G1 Z-3
G0 Z10
G0 X100 Y20
G1 Z-3
G0 Z10
M30
"""


def test_a_hole_pecked_in_steps_is_one_hole_at_its_deepest(tmp_path, exx, capsys):
    """Consecutive plunges at one X Y are one hole (its deepest peck); a hole drilled again after
    another is a hole again (hand-counted: 5 holes of 11 plunges)."""
    machine, fitted = exx
    (tmp_path / "pecked.nc").write_text(PECKED)
    smap = program_error_map(machine, fitted, tmp_path / "pecked.nc", normal="auto")
    assert smap.normal_kind == "holes"
    holes = np.array([[10, 5], [50, 5], [100, 20], [0, 0], [100, 20]], float)
    np.testing.assert_allclose(smap.tips[:, :2], holes, rtol=0, atol=1e-9)
    np.testing.assert_allclose(smap.tips[:, 2], -3.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(smap.dn_before_um, 0.04 * holes[:, 0], rtol=0, atol=1e-6)
    rc = main(["render", "xfyz", str(tmp_path / "model.json"), str(tmp_path / "pecked.nc"),
               "-o", str(tmp_path / "map.png")])
    text = capsys.readouterr()
    assert rc == 0 and "holes: 5 (plunges along the tool axis" in text.out
    assert "not drawn" not in text.out + text.err


def test_a_milled_program_is_no_hole_map(tmp_path, exx):
    machine, fitted = exx
    assert program_error_map(machine, fitted, tmp_path / "slot.nc", normal="auto").normal_kind != "holes"


def test_the_hole_figure_draws_each_hole_and_its_arrow(tmp_path, exx):
    pytest.importorskip("matplotlib")
    from mtcomp.viz.render import _panels, build_holes_figure
    machine, fitted = exx
    smap = program_error_map(machine, fitted, tmp_path / "cycle.nc", normal="auto")
    fig, axes, im = build_holes_figure(smap, _panels(smap), (0.0, 4.0), 1000.0, (800, 400), None)
    try:
        ax = axes[0]
        np.testing.assert_allclose(im.get_offsets(), _holes_of(CYCLE), rtol=0, atol=1e-9)
        np.testing.assert_allclose(im.get_array(), [0.4, 2.0, 4.0], rtol=0, atol=1e-6)
        quiver = [c for c in ax.collections if type(c).__name__ == "Quiver"][0]
        # the arrows: 1000 times the error across the tool axis, in mm (0.04 x um along X)
        np.testing.assert_allclose(quiver.U, [0.4e-3 * 1000, 2.0e-3 * 1000, 4.0e-3 * 1000],
                                   rtol=1e-6, atol=0)
        np.testing.assert_allclose(quiver.V, 0.0, rtol=0, atol=1e-9)
        assert "position error RMS" in ax.get_title() and "depth error RMS 0.00 um" in ax.get_title()
        assert ax.get_xlabel() == "X (mm)" and ax.get_ylabel() == "Y (mm)"
    finally:
        import matplotlib.pyplot as plt
        plt.close(fig)


def test_render_of_a_drilling_program_writes_a_hole_map(tmp_path, exx, capsys):
    pytest.importorskip("matplotlib")
    out = tmp_path / "map.png"
    rc = main(["render", "xfyz", str(tmp_path / "model.json"), str(tmp_path / "cycle.nc"),
               "-o", str(out)])
    text = capsys.readouterr().out
    assert rc == 0 and out.is_file() and out.with_suffix(".vtp").is_file()
    assert "holes: 3 (drilling cycles)" in text
    assert "hole position RMS" in text and "max 4.000 um" in text


def test_holes_asked_of_a_program_without_holes_is_one_line(tmp_path, exx, capsys):
    rc = main(["render", "xfyz", str(tmp_path / "model.json"), str(tmp_path / "slot.nc"),
               "-o", str(tmp_path / "map.png"), "--normal", "holes"])
    err = capsys.readouterr().err
    assert rc == 2 and "drills no hole" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "map.png").exists()


# ------------------------------------------------------------------------------ paths in space
#: two fences of moves along Y and Z at x = 10 and 30 mm (rapids between them)
FENCES = """G21 G90
G0 X10 Y0 Z5
G1 Z-10 F100
G1 Y10
G1 Z0
G1 Y20
G0 Z5
G0 X30 Y0
G1 Z-10
G1 Y10
G0 Z5
M30
"""
TORT = Path(__file__).parent / "data" / "gcode_corpus" / "linuxcnc_tort.ngc"


def test_a_path_map_shows_the_deviation_across_the_path(tmp_path, exx):
    """EXX moves the tip along X only: across moves along Y and Z that is all of it, 0.04 x um."""
    machine, fitted = exx
    (tmp_path / "fences.nc").write_text(FENCES)
    smap = program_error_map(machine, fitted, tmp_path / "fences.nc", normal="path")
    assert smap.normal_kind == "path"
    np.testing.assert_allclose(smap.dn_before_um, 0.04 * smap.tips[:, 0], rtol=0, atol=1e-6)
    assert sorted(set(smap.tips[:, 0].round(6))) == [10.0, 30.0]
    # the lines are the feed moves: 4 at x = 10, 2 at x = 30 (the rapids between are not drawn)
    assert smap.segments.shape == (6, 2)
    ends = smap.tips[smap.segments]
    assert np.all(ends[:, 0, 0] == ends[:, 1, 0])


def test_a_path_along_the_error_shows_none(tmp_path, exx):
    machine, fitted = exx
    (tmp_path / "along.nc").write_text("G21 G90\nG0 X0 Y0 Z0\nG1 X50 F100\nG1 X100\nM30\n")
    smap = program_error_map(machine, fitted, tmp_path / "along.nc", normal="path")
    np.testing.assert_allclose(smap.dn_before_um, 0.0, rtol=0, atol=1e-9)


def test_a_tortuous_path_is_drawn_as_lines_not_slivers(exx):
    """LinuxCNC's tort.ngc wanders in space: as a tool-tip surface most of it would be walls seen
    edge-on (slivers); auto draws the path."""
    machine, fitted = exx
    smap = program_error_map(machine, fitted, TORT, normal="auto")
    assert smap.normal_kind == "path" and smap.info.get("path_segments")
    assert smap.triangles.shape[0] == 0 and smap.segments.shape[0] > 1000
    pytest.importorskip("pyvista")
    from mtcomp.viz.render import to_polydata
    poly = to_polydata(smap)
    assert poly.n_lines == smap.segments.shape[0] and poly.faces.size == 0


# ------------------------------------------------------------------ pairing a split program
def test_the_alignment_is_the_least_total_difference_over_every_monotone_pairing():
    """Random runs (ends a few um apart, corrected, with pieces added): the alignment's total
    difference equals the least over every increasing choice (brute force)."""
    from itertools import combinations

    from mtcomp.viz.program import _aligned
    rng = np.random.default_rng(3)
    tol = np.array([0.05, 0.05])
    for _ in range(30):
        n, extra = int(rng.integers(2, 6)), int(rng.integers(1, 4))
        a = np.cumsum(rng.uniform(0.001, 0.02, (n, 2)), axis=0)
        keep = np.sort(rng.choice(n + extra, n, replace=False))
        b = np.cumsum(rng.uniform(0.001, 0.02, (n + extra, 2)), axis=0)
        b[keep] = a + rng.normal(0, 0.002, a.shape)

        def cost(js):
            return sum(np.max(np.abs(b[j] - a[i]) / tol) for i, j in enumerate(js))
        got = _aligned(a, b, tol)
        assert np.all(np.diff(got) > 0)
        best = min(cost(c) for c in combinations(range(n + extra), n))
        np.testing.assert_allclose(cost(got), best, rtol=1e-12, atol=0)


def test_a_long_thin_part_is_drawn_stretched_and_says_so(tmp_path, exx):
    """A 900 x 20 mm contour to scale is a hairline: drawn stretched, 'not to scale' in the title;
    a 20 x 20 mm square stays to scale."""
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    from mtcomp.viz.render import _panels, build_contour_figure
    machine, fitted = exx
    for name, (w, h), stretched in (("long.nc", (900, 20), True), ("square.nc", (20, 20), False)):
        (tmp_path / name).write_text(f"G21 G90\nG0 X0 Y0 Z5\nG1 Z-1 F100\nX{w}\nY{h}\nX0\nY0\n"
                                     "G0 Z5\nM30\n")
        smap = program_error_map(machine, fitted, tmp_path / name, normal="in-plane")
        fig, axes, _ = build_contour_figure(smap, _panels(smap), (-1.0, 1.0), None, (800, 400), None)
        try:
            assert (axes[0].get_aspect() == "auto") == stretched
            assert ("not to scale" in axes[0].get_title()) == stretched
        finally:
            plt.close(fig)


def test_a_program_of_walls_only_is_drawn_as_its_path_with_its_uncorrected_moves_grey(tmp_path):
    """The real Sinumerik 840D program of the corpus, on a machine of its axes (B table): seen
    along Z every triangle of its tool-tip surface is a wall (1458 of 1458 steeper than 80 deg),
    which a map from above draws as nothing; auto draws the path. Two of its points stand where
    the program has not given every axis (uncorrected): drawn grey as lines of the path's width
    (the old code passed the line width twice there, and pyvista failed)."""
    pv = pytest.importorskip("pyvista")
    from test_gcode_corpus import _machine_file, _model_file

    from mtcomp.machine import load_machine
    from mtcomp.models import load_model
    from mtcomp.viz.render import render_error_map
    prog = Path(__file__).parent / "data" / "gcode_corpus" / "gcodeworkshop_SINUMERIK840D.nc"
    machine_path = _machine_file(tmp_path, "BFXYZ")
    machine = load_machine(machine_path)
    fitted = load_model(_model_file(tmp_path, machine_path))
    smap = program_error_map(machine, fitted, prog, normal="auto")
    assert smap.normal_kind == "path" and smap.info.get("path_segments")
    assert smap.triangles.shape[0] == 0 and smap.segments.shape[0] > 1000
    assert smap.uncorrected.any()
    res = render_error_map(smap, tmp_path / "m.png", window_size=(500, 300), backend="pyvista")
    back = pv.read(res.vtp)
    assert back.n_lines == smap.segments.shape[0]
    np.testing.assert_array_equal(back.cell_data["uncorrected"],
                                  np.any(smap.uncorrected[smap.segments], axis=1))
