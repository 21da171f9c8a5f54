"""What controllers accept that a strict reading of RS-274 would not, each against a hand-derived
case on both reader and writer paths: absolute arc centres (G90.1), arcs whose end radius is off
the start radius within LinuxCNC's tolerance (a spiral), polar words with a repeat count in a G91
drilling cycle, U V W words of axes the model does not have."""
import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks
from test_toolpaths_output import _write_with, gcode_path  # noqa: F401  (the fixture)

XFYZ = load_machine("xfyz")


def _ends(tmp_path, text, **kw):
    p = tmp_path / "p.nc"
    p.write_text(text)
    return np.vstack([c.end for c in iter_segment_chunks(p, XFYZ, **kw)])


def test_g90_1_reads_the_centre_as_a_position(tmp_path, gcode_path):
    # from (2, 0) to (8, 0) clockwise about the centre (5, 0) (I5 J0 absolute): radius 3, over
    # the top (5, 3); read as offsets the centre (7, 0) would leave the end 1 from it (refused)
    ends = _ends(tmp_path, "G21 G90 G90.1\nG0 X2 Y0 Z0\nG2 X8 Y0 I5 J0 F100\nM30\n")
    arc = ends[1:]
    np.testing.assert_allclose(np.hypot(arc[:, 0] - 5.0, arc[:, 1]), 3.0, rtol=0, atol=1e-12)
    assert arc[:, 1].max() == pytest.approx(3.0, rel=0, abs=1e-3)
    with pytest.raises(InputError, match="radius"):
        _ends(tmp_path, "G21 G90 G91.1\nG0 X2 Y0 Z0\nG2 X8 Y0 I5 J0 F100\nM30\n")
    with pytest.raises(InputError, match="without both I and J"):
        _ends(tmp_path, "G21 G90 G90.1\nG0 X2 Y0 Z0\nG2 X8 Y0 I5 F100\nM30\n")


def test_g90_1_centre_moves_with_the_correction(tmp_path, gcode_path):
    text = "G21 G90 G90.1\nG0 X2 Y0 Z0\nG2 X8 Y0 I5 J0 F100\nG91.1\nG3 X2 Y0 I-3 J0\nM30\n"
    shift = lambda p: np.tile([0.001, 0.002, 0.0], (len(p), 1))      # noqa: E731
    out = _write_with(tmp_path, text, field=shift).splitlines()
    # by hand: the whole arc shifted by (1, 2) um: its absolute centre (5, 0) too; the
    # incremental offsets of the next arc (G91.1) do not change
    assert out[2] == "G2 X8.0010 Y0.0020 I5.0010 J0.0020 F100"
    assert out[4] == "G3 X2.0010 Y0.0020 I-3 J0"


def test_an_arc_whose_end_radius_is_off_is_the_controllers_spiral(tmp_path, gcode_path):
    # a quarter turn counter-clockwise from (1, 0) in about the origin to (0, 1.002) in: 0.002 in
    # is within LinuxCNC's 2 sqrt(2) * 0.001 in, so the controller runs a spiral whose radius goes
    # linearly with the angle from 1 to 1.002 in
    ends = _ends(tmp_path, "G20 G90\nG0 X1 Y0 Z0\nG3 X0 Y1.002 I-1 J0 F10\nM30\n")[1:] / 25.4
    angle = np.arctan2(ends[:, 1], ends[:, 0])
    assert len(ends) > 10 and angle.min() > 0
    np.testing.assert_allclose(np.hypot(ends[:, 0], ends[:, 1]), 1 + 0.002 * angle / (np.pi / 2),
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("text, accepted", [
    ("G21\nG0 X10 Y0\nG3 X0 Y10.025 I-10 J0", True),       # 0.025 mm < 0.0283 mm
    ("G21\nG0 X10 Y0\nG3 X0 Y10.03 I-10 J0", False),       # over it, and over 0.1 % of 10 mm
    ("G21\nG0 X100 Y0\nG3 X0 Y100.09 I-100 J0", True),     # over it, within 0.1 % of 100 mm
    ("G20\nG0 X1 Y0\nG3 X0 Y1.0028 I-1 J0", True),         # 0.0028 in < 0.00283 in
    ("G20\nG0 X1 Y0\nG3 X0 Y1.0029 I-1 J0", False),
    ("G20\nG0 X1000 Y0\nG3 X0 Y1000.29 I-1000 J0", False),  # over 100 times 0.00283 in
])
def test_the_arc_radius_rule_is_linuxcncs(tmp_path, text, accepted):
    if accepted:
        assert len(_ends(tmp_path, text + " F100\nM30\n")) > 2
    else:
        with pytest.raises(InputError, match="arc radius inconsistent"):
            _ends(tmp_path, text + " F100\nM30\n")


def test_polar_words_with_a_repeat_count_drill_the_circle(tmp_path, gcode_path):
    # LinuxCNC's bolt circle: from (1.5, 0) in, six holes 60 deg apart on the 1.5 in radius,
    # R 0.1 in above the initial level 0 each time, the bottom 0.5 in below R
    p = tmp_path / "p.ngc"
    p.write_text("G20 G17 G90\nG0 X1.5 Y0 Z0\nG91 G81 R.1 Z-.5 ^60 L6 F10\nM2\n")
    chunks = list(iter_segment_chunks(p, XFYZ))
    holes = np.vstack([c.end[c.cycle] for c in chunks]) / 25.4
    angle = np.radians(60.0 * np.arange(1, 7))
    np.testing.assert_allclose(holes, np.stack([1.5 * np.cos(angle), 1.5 * np.sin(angle),
                                                np.full(6, -0.4)], axis=1), rtol=0, atol=1e-6)
    # in G90 each repeat would drill the same place: not what the program means, refused
    p.write_text("G20 G17 G90\nG0 X1.5 Y0 Z0\nG81 R.1 Z-.5 ^60 L6 F10\nM2\n")
    with pytest.raises(InputError, match="incremental"):
        list(iter_segment_chunks(p, XFYZ))


def test_u_v_w_words_pass_through_and_the_other_axes_are_corrected(tmp_path, gcode_path):
    # a quill W: the line with W alone is no motion of the model (kept byte for byte), a line with
    # X and W gets its X corrected and its W as written; no W word is ever added
    text = "G21 G90\nG0 X1 Y2 Z3\ng1 w100 f2000 (drill)\nG0 X4 W0\nG91 W-5\nM30\n"
    shift = lambda p: np.tile([0.001, 0.0, 0.0], (len(p), 1))      # noqa: E731
    out = _write_with(tmp_path, text, field=shift).splitlines()
    assert out == ["G21 G90", "G0 X1.0010 Y2 Z3", "g1 w100 f2000 (drill)", "G0 X4.0010 W0",
                   "G91 W-5", "M30"]
    np.testing.assert_allclose(_ends(tmp_path, text), [[1, 2, 3], [4, 2, 3]], rtol=0, atol=0)


def test_u_v_w_words_are_said_once(tmp_path, capsys):
    from test_compensate_cli import _model, _run
    _machine, _fitted, model = _model(tmp_path, "xfyz", seed=8)
    p = tmp_path / "w.nc"
    p.write_text("G21 G90\nG0 X1 Y2 Z3\nG1 W100 F2000\nG0 W0\nG1 X4 F100\nM30\n")
    code, stdout, err = _run(["compensate", "xfyz", str(model), str(p), "-o",
                              str(tmp_path / "o.nc")], capsys)
    assert code == 0, err
    assert stdout.count("axis words U, V, W (axes the machine model does not have) pass through "
                        "unchanged and uncorrected") == 1


def test_rigid_tapping_passes_through_and_ends_where_it_started(tmp_path, gcode_path):
    # G33.1: to Z-10 synchronised with the spindle and back to Z5, the line as written; Z is
    # known at 5 after it (the next block may write its corrected Z); X Y in the tapping mode
    # are another tap at the given X Y and back
    text = "G21 G90\nG0 X1 Y2 Z5\nG33.1 Z-10 K1.25\nZ-12\nG0 X3\nM30\n"
    np.testing.assert_allclose(_ends(tmp_path, text), [[1, 2, 5], [3, 2, 5]], rtol=0, atol=0)
    out = _write_with(tmp_path, text).splitlines()
    # by hand: field (1e-4 z, -2e-4 z, 3e-4 x) mm at each end (Y's written value is unchanged)
    assert out == ["G21 G90", "G0 X1.0005 Y1.9990 Z5.0003", "G33.1 Z-10 K1.25", "Z-12",
                   "G0 X3.0005 Z5.0009", "M30"]
    # in G91 every line stays incremental: X2 -> X3 move by 1 with the same X correction (X1
    # kept), Z's correction grows by 3e-4 * 1 at each (Z0.0003 added)
    out = _write_with(tmp_path, "G21 G90\nG0 X1 Y2 Z5\nG91 G0 X1\nG33.1 Z-15 K1.25\nG0 X1\nM30\n")
    assert out.splitlines()[2:] == ["G91 G0 X1 Z0.0003", "G33.1 Z-15 K1.25", "G0 X1 Z0.0003",
                                    "M30"]


def test_a_file_of_subroutines_only_runs_nothing_and_says_so(tmp_path):
    # nothing in it runs (an ngcgui file is called by another program, with its arguments): no
    # move, and a note naming its first subroutine (compensate writes it unchanged)
    from mtcomp.toolpaths.source import open_program
    body = "(a library)\no<hole> sub\nG0 X#1 Y#2\nG1 Z-1 F100\no<hole> endsub\n"
    p = tmp_path / "p.nc"
    p.write_text(body)
    with open_program(p) as src:
        assert not any(len(c.end) for c in iter_segment_chunks(src, XFYZ))
        assert src.notes == ["note: a file of subroutines only (o<hole> sub ... endsub at line 2, "
                             "called by no line of it): nothing in it runs, so nothing in it is "
                             "corrected; compensate the program that calls it, with the "
                             "subroutine in it"]
    # called once from the same file, it runs
    ends = _ends(tmp_path, "G21 G90\n" + body + "o<hole> call [1] [2]\nM2\n")
    np.testing.assert_allclose(ends, [[1, 2, 0], [1, 2, -1]], rtol=0, atol=0)


@pytest.mark.parametrize("dialect", ["fanuc", "haas"])
def test_u_w_words_are_refused_where_lathes_read_them_as_incremental_x_z(tmp_path, dialect):
    p = tmp_path / "p.nc"
    p.write_text("G21 G90\nG0 X10. Y0 Z5.\nG1 U2 W-1 F100\nM30\n")
    with pytest.raises(InputError) as exc:
        list(iter_segment_chunks(p, XFYZ, dialect=dialect))
    assert exc.value.line == 3 and "incremental X and Z" in exc.value.message
    list(iter_segment_chunks(p, XFYZ, dialect="linuxcnc"))  # elsewhere axes the model has not


def test_applying_a_program_offset_without_its_source_is_a_clear_error(tmp_path):
    from mtcomp.toolpaths.offsets import ProgramSetup
    from mtcomp.toolpaths.source import open_program
    p = tmp_path / "p.nc"
    p.write_text("G21 G90\nG10 L2 P1 X100 Y0 Z0\nG0 X1 Y2 Z3\nM30\n")
    with open_program(p) as src:
        chunk = next(iter(iter_segment_chunks(src, XFYZ)))
        with pytest.raises(ValueError, match="needs the ProgramSource"):
            ProgramSetup(XFYZ).apply(chunk)
        ProgramSetup(XFYZ).apply(chunk, src)
