"""Maps of planar (2-D) programs: the deviation across the contour in its plane, on a hand-made
square contour with a known in-plane error, and the choice between in-plane and surface maps.

The model has one term: EXX, the positioning error of X, growing by 40 um per metre of X
(``EXX_1 = 40``): the tool tip stands at x + 40e-6 x. On the square -10 <= x, y <= 10 the walls
x = +10 and x = -10 are off by +0.4 um and -0.4 um along X, that is 0.4 um outward (along their
outward normals +X and -X); the walls y = +-10 run along X and are off by nothing across them.
A map along the surface normal (Z) shows nothing of this."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp import InputError, load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.viz.surface import planar_levels, program_error_map, read_program_points

SQUARE = """G21 G90
G0 X-10 Y-10 Z5
G1 Z-1 F300
G1 X10 F600
Y10
X-10
Y-10
G0 Z5
M30
"""


@pytest.fixture()
def exx(tmp_path):
    machine = load_machine("xfyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine))
    fitted.params.set_file_value("EXX_1", 40.0)
    save_model(tmp_path / "model.json", fitted)
    (tmp_path / "square.nc").write_text(SQUARE)
    return machine, fitted


def _wall_dn(smap):
    """dn (um) per wall, keyed by its outward normal, from the map's contour vertices."""
    out = {}
    for n, dn in zip(np.round(smap.normals).astype(int), smap.dn_before_um):
        out.setdefault(tuple(n.tolist()), []).append(dn)
    return {k: np.array(v) for k, v in out.items()}


def test_square_contour_shows_its_in_plane_error(tmp_path, exx):
    machine, fitted = exx
    smap = program_error_map(machine, fitted, tmp_path / "square.nc", normal="in-plane")
    assert smap.normal_kind == "in-plane"
    walls = _wall_dn(smap)
    assert sorted(walls) == [(-1, 0, 0), (0, -1, 0), (0, 1, 0), (1, 0, 0)]
    np.testing.assert_allclose(walls[(1, 0, 0)], 0.4, rtol=0, atol=1e-9)
    np.testing.assert_allclose(walls[(-1, 0, 0)], 0.4, rtol=0, atol=1e-9)
    np.testing.assert_allclose(walls[(0, 1, 0)], 0.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(walls[(0, -1, 0)], 0.0, rtol=0, atol=1e-9)
    assert smap.triangles.shape == (8, 3)                  # a band of two triangles per wall
    # a pocket: the normals point into it, the same error reads as the tool digging in
    inner = program_error_map(machine, fitted, tmp_path / "square.nc", normal="in-plane",
                              flank_side="inner")
    walls = _wall_dn(inner)
    np.testing.assert_allclose(walls[(-1, 0, 0)], -0.4, rtol=0, atol=1e-9)   # the wall x = +10


def test_the_surface_map_of_the_square_shows_nothing_and_auto_chooses_in_plane(tmp_path, exx):
    machine, fitted = exx
    flat = program_error_map(machine, fitted, tmp_path / "square.nc", normal="surface")
    assert np.abs(flat.dn_before_um).max() < 1e-12        # the normal is Z: X error unseen
    auto = program_error_map(machine, fitted, tmp_path / "square.nc")
    assert auto.normal_kind == "surface"                   # the library default stays as it was
    auto = program_error_map(machine, fitted, tmp_path / "square.nc", normal="auto")
    assert auto.normal_kind == "in-plane" and auto.stats()["max_before_um"] == pytest.approx(
        0.4, rel=0, abs=1e-9)


def test_a_contour_in_a_plane_the_tool_is_tilted_to_is_warned_of(tmp_path, exx):
    """The square cut in the plane z = x / 2 (a lead angle of 26.6 deg between the tool and the
    plane's normal): the surface map fills its inside with one face whose normal is the plane's,
    so it shows the X error only along that normal, (-1, 0, 2) / sqrt(5) times 0.4 um at the
    walls x = +-10, and says so; the square in z = 0 gets the tool-axis warning instead."""
    machine, fitted = exx
    tilted = SQUARE.replace("G1 Z-1 F300", "G1 Z-6 F300").replace("G1 X10 F600", "G1 X10 Z4 F600")
    tilted = tilted.replace("\nX-10\nY-10", "\nX-10 Z-6\nY-10")
    (tmp_path / "tilted.nc").write_text(tilted)
    smap = program_error_map(machine, fitted, tmp_path / "tilted.nc", normal="surface")
    assert any("the normals are all one (a flat face) and the tool is tilted to them" in n
               for n in smap.notes)
    np.testing.assert_allclose(np.abs(smap.dn_before_um).max(), 0.4 / np.sqrt(5), rtol=1e-6,
                               atol=0)
    flat = program_error_map(machine, fitted, tmp_path / "square.nc", normal="surface")
    assert not any("tilted to them" in n for n in flat.notes)
    assert any("the normals all lie along the tool axis" in n for n in flat.notes)


def test_planar_levels(tmp_path):
    machine = load_machine("xfyz")

    def levels(text):
        p = tmp_path / "p.nc"
        p.write_text("G21 G90\n" + text)
        return planar_levels(read_program_points(p, machine), machine)
    assert levels(SQUARE) == 1
    # the same contour in two step-downs, with a ramp between them (3 % of the path)
    assert levels("G0 X0 Y0 Z1\nG1 Z-1 F100\nX20\nY20\nX0\nY0\nX5 Z-2\nX20\nY20\nX0\nY0\nX5\n") == 2
    # a sloped raster: few heights, but every cut climbs: a surface, not a contour
    assert levels("G0 X0 Y0 Z1\nG1 Z0 F100\nX10 Z1\nY5\nX0 Z0\nY10\nX10 Z1\n") == 0
    # waterline passes over a form on more than ten heights (a 45 deg pyramid: each ring 1 mm
    # inside the one below): a surface
    rings = "".join(f"G1 X{z} Y{z} Z{z - 12}\nX{20 - z}\nY{20 - z}\nX{z}\nY{z}\n" for z in range(12))
    assert levels("G0 X0 Y0 Z1\nF100\n" + rings) == 0
    # the same square on twelve heights (a profile in twelve step-downs): each level's contour on
    # the one below, a wall: planar
    rings = "".join(f"G1 Z{-z}\nX10\nY10\nX0\nY0\n" for z in range(12))
    assert levels("G0 X0 Y0 Z1\nF100\n" + rings) == 12


def test_render_says_what_it_maps(tmp_path, exx, capsys):
    from mtcomp.cli import main
    args = ["render", "xfyz", str(tmp_path / "model.json"), str(tmp_path / "square.nc"),
            "--backend", "matplotlib", "--size", "300x150", "-o"]
    assert main(args + [str(tmp_path / "a.png")]) == 0
    out = capsys.readouterr().out
    assert "contour: 4 wall segments in 1 plane across the tool axis (in-plane map" in out
    assert "before: RMS 0.283 um, max 0.400 um (deviation along the contour's normal" in out
    assert main(args + [str(tmp_path / "b.png"), "--normal", "surface"]) == 0
    out = capsys.readouterr().out
    assert "before: RMS 0.000 um, max 0.000 um" in out
    warning = [line for line in out.splitlines() if line.startswith("warning:")]
    assert len(warning) == 1 and "--normal in-plane" in warning[0]


def test_in_plane_map_of_a_program_without_a_contour_is_refused(tmp_path, exx):
    machine, fitted = exx
    p = tmp_path / "drill.nc"
    p.write_text("G21 G90\nG0 X1 Y1 Z5\nG1 Z-1 F100\nG0 Z5\nX2\nG1 Z-1\nG0 Z5\n")
    with pytest.raises(InputError, match="no feed move across the tool axis"):
        program_error_map(machine, fitted, p, normal="in-plane")
    # auto: a program that only plunges along the tool axis drills holes (tests/test_viz_holes.py)
    assert program_error_map(machine, fitted, p, normal="auto").normal_kind == "holes"
