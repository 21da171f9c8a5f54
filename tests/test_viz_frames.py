"""render under a frame the program moves itself (G52, G68, a mirror image, scaling): the map of the
program and of its compensated version is the map of the same motion written flat by hand (the
second formulation of tests/test_toolpaths_frames.py), point for point and deviation for deviation:
the map sees the positions where the controller puts them."""
import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import load_model
from mtcomp.viz.surface import program_error_map, read_program_points
from test_compensate_cli import _model, _run
from test_toolpaths_frames import CASES, compensated_both, programs_of

XFYZ = load_machine("xfyz")


@pytest.mark.parametrize("code", ["G68", "G51.1", "G52"])
def test_the_map_under_a_frame_is_the_map_of_the_flat_program(tmp_path, capsys, code):
    dialect = CASES[code][0]
    maps = {}
    # errors within the default correction bound (50 um), so the compensated map shows them removed
    for name, _text, prog, out, model in compensated_both(tmp_path, capsys, code, 5.0):
        maps[name] = program_error_map(XFYZ, load_model(model, XFYZ),
                                       read_program_points(prog, XFYZ, dialect), out,
                                       tool_radius_mm=0.0, normal="path")
    frame, flat = maps["frame"], maps["flat"]
    assert frame.points.shape == flat.points.shape
    # the flat program's words are the placed ones rounded to 6 decimals
    np.testing.assert_allclose(frame.points, flat.points, rtol=0, atol=1e-6)
    np.testing.assert_allclose(frame.dev_before, flat.dev_before, rtol=0, atol=1e-8)
    # the compensated programs' words differ in their last written decimal (the frame's words are
    # the flat ones turned back): 2e-6 mm as the compensation test allows
    np.testing.assert_allclose(frame.dev_after, flat.dev_after, rtol=0, atol=2e-6)
    assert np.abs(flat.dev_before).max() > 1e-3        # a map with something on it
    before, after = (np.linalg.norm(d, axis=1) for d in (frame.dev_before, frame.dev_after))
    # corrected: the written arcs keep within the chord tolerance (1 um) of the corrected path
    assert np.median(after) < 0.5 * np.median(before)


def test_render_draws_a_program_under_g68(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    dialect = CASES["G68"][0]
    _machine, _fitted, model = _model(tmp_path, "xfyz", seed=8, scale=60.0)
    prog, out = tmp_path / "p.nc", tmp_path / "p.out.nc"
    prog.write_text(programs_of("G68")["frame"])
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--quiet",
                 "--dialect", dialect]) == 0
    png = tmp_path / "map.png"
    code, _o, err = _run(["render", "xfyz", str(model), str(prog), "--compensated", str(out),
                          "-o", str(png), "--backend", "matplotlib", "--dialect", dialect], capsys)
    assert code == 0, err
    assert png.is_file()


@pytest.mark.parametrize("code", ["G68", "G51", "G52"])
def test_the_report_s_positions_are_placed_like_the_program_s(tmp_path, capsys, code):
    """render --report: BLOCKS.csv gives a block's words, which under a frame the program set are
    not where the machine goes; placed by that frame they are where the compensated program, read
    the same way, puts the tool (within the tolerances below). Before, the
    report's words were taken as positions: off by the frame (a new user saw 5 mm under G51 P1.5)."""
    from mtcomp.viz.program import report_points
    dialect = CASES[code][0]
    _machine, _fitted, model = _model(tmp_path, "xfyz", seed=8, scale=5.0)
    prog, out, rep = tmp_path / "p.nc", tmp_path / "o.nc", tmp_path / "b.csv"
    prog.write_text(programs_of(code)["frame"])
    code_, _o, err = _run(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--dialect",
                           dialect, "--subdivide-tol-um", "0", "--quiet", "--report", str(rep)], capsys)
    assert code_ == 0, err
    original = read_program_points(prog, XFYZ, dialect)
    assert original.local is not None and original.local.any()
    placed = report_points(original, rep, XFYZ).q
    written = read_program_points(out, XFYZ, dialect).q
    assert placed.shape == written.shape
    # the written arcs keep within 1 um of the corrected path in the program's frame (2 um on the
    # machine under G51 P2), and each is read back as chords of its own: 5 um. Unplaced, the
    # report's words were off by the frame: millimetres
    np.testing.assert_allclose(placed, written, rtol=0, atol=5e-3)
