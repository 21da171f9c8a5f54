"""What render leaves out of a map it says: a program that drills holes with drilling cycles and
also mills is mapped by the moves that cut (the holes left out and counted on the map), and a hole
map of it counts the feed moves it does not draw.

The model has one term, EXX = 40 um per metre of X (``EXX_1 = 40``): the tip stands at
x (1 + 40e-6), so the wall the slot cuts at x = 40 mm (line 10, along Y) is off by 1.6 um across
it, and the wall along X (line 9) by nothing across it (hand-derived, as in
tests/test_viz_inplane.py). The lines are counted by hand in the program below."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.viz.surface import program_error_map
from test_viz_holes import CYCLE
from test_viz_inplane import exx  # noqa: F401  (the fixture: the EXX model)

#: three holes by G81 (lines 3-5), then a slot: a plunge (line 8) and two cutting moves (9, 10)
MIXED = CYCLE.replace("G0 Z10\nM30\n", "G0 X0 Y-10 Z5\nG1 Z-1 F100\nG1 X40\nY-20\nG0 Z10\nM30\n")
HOLES_LEFT_OUT = ("3 holes of drilling cycles (lines 3 to 5) not drawn: the map shows the moves "
                  "that cut; --normal holes maps the holes")
MOVES_LEFT_OUT = ("3 feed moves (lines 8 to 10) not drawn: the map shows the holes only; --normal "
                  "auto, in-plane, surface or path maps the moves that cut")


@pytest.fixture()
def mixed(tmp_path, exx):
    (tmp_path / "mixed.nc").write_text(MIXED)
    return exx


def test_a_program_that_mills_beside_its_holes_maps_the_cut_and_says_the_holes(tmp_path, mixed):
    machine, fitted = mixed
    smap = program_error_map(machine, fitted, tmp_path / "mixed.nc", normal="auto")
    assert smap.normal_kind == "in-plane"
    assert smap.notes == [HOLES_LEFT_OUT]
    drawn = set(smap.line.tolist())
    assert not drawn & {3, 4, 5} and {9, 10} <= drawn
    across_x = np.abs(smap.normals[:, 0]) > 0.99           # the wall at x = 40 (line 10)
    across_y = np.abs(smap.normals[:, 1]) > 0.99           # the wall along X (line 9)
    assert across_x.any() and across_y.any()
    np.testing.assert_allclose(np.abs(smap.dn_before_um[across_x]), 1.6, rtol=0, atol=1e-6)
    np.testing.assert_allclose(smap.dn_before_um[across_y], 0.0, rtol=0, atol=1e-6)


def test_a_hole_map_of_it_says_the_moves_it_does_not_draw(tmp_path, mixed):
    machine, fitted = mixed
    smap = program_error_map(machine, fitted, tmp_path / "mixed.nc", normal="holes")
    assert smap.normal_kind == "holes"
    assert sorted(smap.line.tolist()) == [3, 4, 5]
    assert smap.notes == [MOVES_LEFT_OUT]


def test_a_drilling_program_leaves_nothing_out(tmp_path, mixed):
    machine, fitted = mixed
    (tmp_path / "holes.nc").write_text(CYCLE)
    smap = program_error_map(machine, fitted, tmp_path / "holes.nc", normal="auto")
    assert smap.normal_kind == "holes" and smap.notes == []


def test_render_prints_and_draws_what_it_left_out(tmp_path, mixed, capsys):
    pytest.importorskip("matplotlib")
    out = tmp_path / "map.png"
    assert main(["render", "xfyz", str(tmp_path / "model.json"), str(tmp_path / "mixed.nc"),
                 "-o", str(out), "--backend", "matplotlib"]) == 0
    text = capsys.readouterr().out
    assert f"warning: {HOLES_LEFT_OUT}" in text.splitlines()
    assert out.is_file()


def test_the_travel_note_takes_the_work_offset_given(tmp_path, exx, capsys):
    """A program at X 350..450 is outside X's travel (-400, 400) as axis positions, and inside it
    with G54 at X -100: render notes the travel only where the program's positions, with the work
    offset given, leave it (it noted it with the offset given too, naming the program's
    coordinates as axis positions)."""
    pytest.importorskip("matplotlib")
    (tmp_path / "far.nc").write_text("G54 G0 X350 Y0 Z5\nG1 Z-1 F100\nG1 X450\nG1 Y10\nG0 Z5\nM30\n")
    base = ["render", "xfyz", str(tmp_path / "model.json"), str(tmp_path / "far.nc"),
            "--backend", "matplotlib"]
    assert main(base + ["-o", str(tmp_path / "a.png")]) == 0
    err = capsys.readouterr().err
    assert "outside the travel" in err and "give --work-offset" in err
    assert main(base + ["-o", str(tmp_path / "b.png"), "--work-offset", "G54=X-100,Y0,Z0"]) == 0
    assert "outside the travel" not in capsys.readouterr().err
    assert main(base + ["-o", str(tmp_path / "c.png"), "--work-offset", "G54=X100,Y0,Z0"]) == 0
    assert "plus the work offset given" in capsys.readouterr().err
