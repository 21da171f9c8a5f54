"""Never write a position the program did not give: hand-made hazard programs, checked line by line,
on the compiled and the pure-Python path, with corrections on every axis (so a writer that writes
what it may not would show it). Plus the dialects real CAM posts write."""
import numpy as np
import pytest

from mtcomp import InputError, load_machine
from mtcomp.toolpaths import iter_segment_chunks, read_program, write_corrected
from test_toolpaths_gcode import gcode_path  # noqa: F401  (autouse: compiled and Python path)

XFYZ = load_machine("xfyz")
CBFXYZ = load_machine("cbfxyz")


def _shifted(path, machine, shift_mm=0.002):
    """Write ``path`` with every segment end moved by shift_mm on every axis (rad for rotary ones):
    what a planner that ignored the unknown axes would ask for."""
    out = path.with_name("out.nc")
    corr = [(c, c.end + shift_mm, np.ones(len(c), int)) for c in iter_segment_chunks(path, machine)]
    write_corrected(path, out, machine, iter(corr))
    return out.read_text().splitlines()


def test_fusion_home_then_xy_then_tool_length(tmp_path):
    # Fusion's Haas/Fanuc start: Z homed, XY positioned, then G43 Z10. H1. The old writer turned
    # line 7 into "G0 X-31.1578 Y33.6893 Z-0.0009": a rapid to work Z0 with no tool length.
    p = tmp_path / "in.nc"
    p.write_text("%\nO1001\nG90 G94 G17\nG21\nG28 G91 Z0.\nG90\nG0 X-31.161 Y33.689\n"
                 "G43 Z10. H1\nG1 Z-1. F300.\nX-20.\nM30\n%\n")
    b = read_program(p, XFYZ).blocks
    assert [x.line for x in b] == [7, 8, 9, 10]
    assert [x.known.tolist() for x in b] == [[True, True, False]] + [[True] * 3] * 3
    out = _shifted(p, XFYZ)
    # line 7 names X and Y only: Z is never written before line 8 gives it; then only what changes
    assert out == ["%", "O1001", "G90 G94 G17", "G21", "G28 G91 Z0.", "G90",
                   "G0 X-31.1590 Y33.6910", "G43 Z10.0020 H1", "G1 Z-0.9980 F300.", "X-19.9980",
                   "M30", "%"]


def test_start_with_only_z_gains_nothing(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text("G21 G90\nG0 Z6.\nG0 X10 Y5\nG1 Z-1 F100\n")
    b = read_program(p, XFYZ).blocks
    assert [x.known.tolist() for x in b] == [[False, False, True], [True] * 3, [True] * 3]
    out = _shifted(p, XFYZ)
    assert out[1] == "G0 Z6.0020"          # no X0 Y0 added
    assert out[2] == "G0 X10.0020 Y5.0020"
    assert out[3] == "G1 Z-0.9980 F100"


def test_indexing_move_writes_only_the_rotary_axis(tmp_path):
    # LinuxCNC's b-index.ngc pattern: a B move before anything else, then XYZ
    p = tmp_path / "in.nc"
    p.write_text("G21 G90\nG0 B0\nG0 X0 Y0 Z0\nG1 X1 F70\nB45\nX3\n")
    b = read_program(p, CBFXYZ).blocks
    names = CBFXYZ.axis_names
    assert names == ("X", "Y", "Z", "B", "C")
    assert b[0].known.tolist() == [False, False, False, True, False]
    assert all(not x.known[4] for x in b)          # C never given: never written
    out = _shifted(p, CBFXYZ, shift_mm=np.radians(0.001))
    assert out[1] == "G0 B0.0010"                  # no X0 Y0 Z0 C0
    for line in out[1:]:
        assert "C" not in line
    assert out[2] == "G0 X0 Y0 Z0"           # 1e-3 deg on B: the linear axes keep their text


def test_tool_change_and_work_offset_forget_positions(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text("G0 X1 Y2 Z3\nT2 M6\nG0 X4\nG55\nG0 Y5\nG0 X1 Z2\n")
    b = read_program(p, XFYZ).blocks
    assert [x.known.tolist() for x in b] == [[True] * 3, [True, True, False],
                                             [False, True, False], [True, True, True]]
    out = _shifted(p, XFYZ)
    assert out[2] == "G0 X4.0020"              # Y known, its written value unchanged; Z unknown
    assert out[4] == "G0 Y5.0020"              # after G55 only Y


def test_g53_passes_through_and_cycles_keep_the_known_axes(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text("G0 X0 Y0 Z10\nG53 G0 Z0.\nG0 X5 Y5 Z2\nG98 G81 X5 Y5 Z-3 R2 F100\nX10\n"
                 "G80\nG0 X0 Y0\nG0 Z20\n")
    b = read_program(p, XFYZ).blocks
    assert [x.line for x in b] == [1, 3, 4, 5, 7, 8]
    assert b[1].known.tolist() == [True, True, True]
    # G98 with the R plane at the initial level 2: the cycle leaves the tool there, Z known
    assert b[4].known.tolist() == [True, True, True] and b[4].start[2] == 2.0
    out = _shifted(p, XFYZ)
    src = p.read_text().splitlines()
    assert out[1] == src[1]                                   # G53 as written
    assert out[3:5] == ["G98 G81 X5.0020 Y5.0020 Z-2.9980 R2.0020 F100", "X10.0020"]
    assert out[6] == "G0 X0.0020 Y0.0020"


def test_inverse_time_feed_recomputed_for_split_blocks(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text("G0 X0 Y0 Z0\nG93 G1 X10 F2\nG94 G1 X20 F100\n")
    b = read_program(p, XFYZ).blocks
    assert b[1].feed == pytest.approx(20.0, rel=1e-12, abs=0)   # 10 mm in 1/2 min
    chunks = list(iter_segment_chunks(p, XFYZ))

    def corr():
        for c in chunks:
            pts, counts = [], []
            for r in range(len(c)):
                if c.line[r] == 2:      # split into 2.5 mm and 7.5 mm
                    pts += [c.start[r] + [2.5, 0, 0.001], c.end[r]]
                    counts.append(2)
                else:
                    pts.append(c.end[r])
                    counts.append(1)
            yield c, np.array(pts), np.array(counts)
    out = tmp_path / "out.nc"
    write_corrected(p, out, XFYZ, corr())
    lines = out.read_text().splitlines()
    # each piece keeps the block's time share: 1/2 min * (2.5/10) -> F8, the rest -> F2.66667
    assert lines[1] == "G93 G1 X2.5000 Z0.0010 F8"
    assert lines[2] == "X10.0000 Z0.0000 F2.66667"
    assert lines[3] == "G94 G1 X20 F100"


def test_blanks_inside_words_zero_offsets_and_grbl_lines(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text("$H\n$X\nG21 G90\nG0 X 1 Y2 Z 10\n?\nG1 Z - 1 F 200\n ~ \n!\nG17 G2 X3 Y2 I1 J0 K0.000\n")
    b = read_program(p, XFYZ).blocks
    np.testing.assert_allclose(b[0].end, [1, 2, 10], rtol=0, atol=0)
    np.testing.assert_allclose(b[1].end, [1, 2, -1], rtol=0, atol=0)
    assert b[1].feed == 200.0
    np.testing.assert_allclose(b[2].centre, [2, 2, -1], rtol=0, atol=1e-12)
    out = tmp_path / "out.nc"
    write_corrected(p, out, XFYZ, None)
    assert out.read_text() == p.read_text()        # nothing to change: every line as written


@pytest.mark.parametrize("text, msg", [
    ("G0 X1\no200 sub\n", "o200 sub without its o200 endsub"),
    ("G0 X1 Y1 Z1\nG43.5 H1 I0 J0 K1\n", "G43.5 (tool centre point control with a tool axis vector"),
    ("M430\nG0 X1\n", "M430 (LinuxCNC switchable kinematics"),
    ("G0 X1\nG1 X#5221\n", "parameter #5221 holds controller state"),
])
def test_refusals_name_the_feature_and_the_line(tmp_path, text, msg):
    p = tmp_path / "in.nc"
    p.write_text(text)
    with pytest.raises(InputError) as exc:
        read_program(p, XFYZ)
    assert msg in str(exc.value) and str(exc.value).count("\n") == 0
    assert exc.value.line == (1 if text.startswith("M430") else 2)


def test_full_circle_stays_full_and_raw_spelling_is_where_the_machine_is(tmp_path):
    # LinuxCNC's tort.ngc: a helical full circle from a point written with 6 decimals. Writing its
    # end with 4 decimals would turn it into a 0.05 um arc; the output must still be a full circle.
    p = tmp_path / "in.nc"
    p.write_text("G21 G90\nG0 X-2.496094 Y37.186053 Z6.807612\n"
                 "G17 G3 F100 I-1.000000 J-1.732051 X-2.496094 Y37.186053 Z10.807612\nG0 Z20\n")
    src = read_program(p, XFYZ).blocks[1]
    for shift in ([0.0, 0.0, 0.003], [2e-5, 0.0, 0.003]):
        corr = [(c, c.end + shift, np.ones(len(c), int)) for c in iter_segment_chunks(p, XFYZ)]
        out = tmp_path / "out.nc"
        write_corrected(p, out, XFYZ, iter(corr))
        back = read_program(out, XFYZ).segments()
        xy = back.end[:, :2]
        # the whole circle is cut: the points reach the far side of it (diameter 4 mm)
        span = np.ptp(xy[back.line > 2], axis=0)
        np.testing.assert_allclose(span, np.ptp(src.points[:, :2], axis=0), rtol=0, atol=2e-3)


def test_fanuc_colon_program_number_and_dos_end_mark_pass_through(tmp_path):
    # Fanuc's ISO program number ':0097' and a DOS Ctrl-Z after the last line, as published
    p = tmp_path / "in.nc"
    p.write_bytes(b"% \r\n:0097\r\n:0098 (SECOND)\r\nN10 G21 G90 G0 X2. Y0 Z5.\r\nM30\r\n%\r\n\x1a")
    b = read_program(p, XFYZ).blocks
    assert [x.line for x in b] == [4]
    out = _shifted(p, XFYZ)
    assert out == ["% ", ":0097", ":0098 (SECOND)", "N10 G21 G90 G0 X2.0020 Y0.0020 Z5.0020", "M30", "%",
                   "\x1a"]
    p.write_text(":0097 X1\n")                 # a colon line with more than a number is refused
    with pytest.raises(InputError, match=":1: unexpected character ':'"):
        read_program(p, XFYZ)


def test_incremental_move_of_an_unknown_axis_passes_through_and_keeps_it_unknown(tmp_path):
    """Haas: G43 H01 without Z, then G91 G0 Z-10.: the controller moves Z from wherever it stands.
    The line passes through as written (incremental), Z stays unknown until the program gives it,
    X and Y named in the same line move by their increments and stay known; the output stays in
    G91 as the source is."""
    p = tmp_path / "in.nc"
    p.write_text("G21 G90\nG0 X10 Y10 Z50\nT1 M6\nG43 H01\nG91 G0 X5 Z-10.\nG0 Y1\nG90 G0 Z20.\n"
                 "G1 X30 F100\n")
    b = read_program(p, XFYZ).blocks
    assert [x.line for x in b] == [2, 6, 7, 8]
    assert b[1].known.tolist() == [True, True, False]
    np.testing.assert_allclose(b[1].end[:2], [15.0, 11.0], rtol=0, atol=0)
    assert b[2].known.tolist() == [True, True, True]
    out = _shifted(p, XFYZ)
    src = p.read_text().splitlines()
    assert out[4] == src[4]                       # as written: the controller's own move
    # X and Y known (X where the passed line took it: the controller's 10.002 + 5, where the
    # shifted X is): the increment of Y is the source's, X and Z not written
    assert out[5] == "G0 Y1"
    assert out[6] == "G90 G0 Z20.0020"                # its own G90 kept
    q = tmp_path / "inc.nc"
    q.write_text("G21 G90\nG0 X0 Y0 Z5\nG91\nG0 X10 Y10\nT1 M6\nG0 Z-10.\nG90 G0 Z20.\n")
    res = _shifted(q, XFYZ)
    # the known increments stay the source's (the shift is constant); the passed line as written
    assert res[3:] == ["G0 X10 Y10", "T1 M6", "G0 Z-10.", "G90 G0 Z20.0020"]


def test_incremental_arc_of_an_unknown_axis_passes_as_written(tmp_path):
    # Z lost by the tool change: the G91 helix runs from wherever Z stands, so it is no block and
    # passes as written; X and Y move by its increments from where the output stands (10.002:
    # the shift), so the next known increment is the source's and Z is written only once the
    # program gives it again
    p = tmp_path / "in.nc"
    p.write_text("G21 G90 G17\nG0 X10 Y10 Z50\nT1 M6\nG91 G2 X10 Y0 Z-1 I5 J0 F100\nG1 X5\n"
                 "G90 G0 Z20.\nG1 X30\n")
    b = read_program(p, XFYZ).blocks
    assert [x.line for x in b] == [2, 5, 6, 7]
    np.testing.assert_allclose(b[1].start[:2], [20.0, 10.0], rtol=0, atol=0)
    out = _shifted(p, XFYZ)
    src = p.read_text().splitlines()
    assert out[3] == src[3]
    assert out[4:] == ["G1 X5", "G90 G0 Z20.0020", "G1 X30.0020"]
