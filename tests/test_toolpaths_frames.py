"""Frame changes a program makes itself: G52 local shift, G68 rotation, mirror images (G51.1, Haas'
G101), scaling (G51). Hand-derived machine positions and output lines under a correction given in
the machine's frame; the compensated program under the frame against the compensation of the same
motion written flat by hand (a second formulation), both replayed by an interpreter of these codes
written here (it shares no code with the reader); each refusal through the command line."""
import math
import re

import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks, write_corrected
from mtcomp.toolpaths.offsets import ProgramSetup
from mtcomp.toolpaths.source import open_program
from test_compensate_cli import _model, _run
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)

XFYZ = load_machine("xfyz")


def _corrected(tmp_path, text, dialect, correction, name="p"):
    """(machine ends (n, 3), known (n, 3), output lines) of ``text`` read by ``dialect`` and
    written with the machine-frame correction ``correction(machine ends) -> (n, 3) mm``."""
    return corrected_with_notes(tmp_path, text, dialect, correction, name)[:3]


def corrected_with_notes(tmp_path, text, dialect, correction, name="p"):
    """:func:`_corrected` and the program's notes, through the same steps as compensate: the setup
    places the rows, takes the correction back to the program's frame and to the words written
    (:meth:`ProgramSetup.written`: a G92 set where the corrected tool stands)."""
    p, out = tmp_path / f"{name}.nc", tmp_path / f"{name}.out.nc"
    p.write_text(text)
    ends, known = [], []
    with open_program(p, dialect) as src:
        setup = ProgramSetup(XFYZ)

        def corrections():
            for chunk in iter_segment_chunks(src, XFYZ):
                mchunk, off = setup.apply(chunk, src)
                ends.append(mchunk.end)
                known.append(chunk.known)
                ones = np.ones(len(chunk), np.int64)
                # as the planner does: a row with an axis the program has not given is not corrected
                pts = mchunk.end + correction(mchunk.end) * chunk.known.all(axis=1)[:, None]
                nominal = setup.to_program(chunk, mchunk.end, ones, off)
                pts = setup.to_program(chunk, pts, ones, off)
                yield chunk, setup.written(chunk, pts, nominal, ones), ones
        write_corrected(src, out, XFYZ, corrections())
        notes = list(src.notes)
    return np.vstack(ends), np.vstack(known), out.read_text().splitlines(), notes


def _constant(c_mm):
    return lambda q: np.broadcast_to(np.asarray(c_mm, float), q.shape)


SQUARE = ("G21 G90 G17\nG68 X0 Y0 R90.\nG0 X10. Y0 Z5.\nG1 X10. Y10. Z0 F500\nG1 X0 Y10.\n"
          "G1 X0 Y0\nG69\nM30\n")


def test_g68_square_places_the_rotated_points_and_turns_the_correction_back(tmp_path, mode):
    """R90 about the origin: program (x, y) is machine (-y, x). A correction of +1 um on machine X
    is, in the program's frame, R(-90) (1, 0) = (0, -1) um: -1 um on program Y, X unchanged."""
    ends, known, lines = _corrected(tmp_path, SQUARE, "fanuc", _constant([0.001, 0, 0]))
    np.testing.assert_allclose(ends, [[0, 10, 5], [-10, 10, 0], [-10, 0, 0], [0, 0, 0]],
                               rtol=0, atol=1e-12)
    assert known.all()
    assert lines[2:6] == ["G0 X10. Y-0.0010 Z5.", "G1 X10. Y9.9990 Z0 F500", "G1 X0 Y9.9990",
                          "G1 X0 Y-0.0010"]
    assert lines[:2] + lines[6:] == ["G21 G90 G17", "G68 X0 Y0 R90.", "G69", "M30"]


def test_g68_approach_directions_are_the_machine_axes(tmp_path, mode):
    """dirs are those of the machine's axes: program +Y (the second move) is machine -X."""
    p = tmp_path / "p.nc"
    p.write_text(SQUARE)
    with open_program(p, "fanuc") as src:
        dirs = np.vstack([c.dirs for c in iter_segment_chunks(src, XFYZ)])
    # machine moves: (0,10,5) from a start not given (directions not known), then -X -Z (Y still
    # not known), then -Y, then +X
    assert dirs[0].tolist() == [0, 0, 0]
    assert dirs[1].tolist() == [-1, 0, -1] and dirs[2].tolist() == [-1, -1, -1]
    assert dirs[3].tolist() == [1, -1, -1]


def test_g52_shift_with_a_correction_linear_in_x(tmp_path, mode):
    """G52 X100 Y50: program (10, 0) is machine (110, 50); the correction 1e-4 x (machine x) is
    11 um there, written on the program's X as it is (a translation). The shift moves nothing: X
    and Y stay known (the move naming X alone keeps Y at 0 + 50); G52 X0 Y0 cancels it."""
    text = ("G21 G90\nG0 X1. Y2. Z3.\nG52 X100. Y50.\nG1 X10. Y0 F300\nG1 X20.\nG52 X0 Y0\n"
            "G1 X5.\nM30\n")
    linear = lambda q: np.column_stack([1e-4 * q[:, 0], 0 * q[:, 0], 0 * q[:, 0]])  # noqa: E731
    ends, known, lines = _corrected(tmp_path, text, "linuxcnc", linear)
    np.testing.assert_allclose(ends, [[1, 2, 3], [110, 50, 3], [120, 50, 3], [5, 50, 3]],
                               rtol=0, atol=1e-12)
    assert known.all()
    # after G52 X0 Y0 the program's Y of the same place reads 50, and the output's position
    # follows the shift (nothing moved): the next line needs no Y word
    assert lines == ["G21 G90", "G0 X1.0001 Y2. Z3.", "G52 X100. Y50.", "G1 X10.0110 Y0 F300",
                     "G1 X20.0120", "G52 X0 Y0", "G1 X5.0005", "M30"]


def test_mirror_of_x_with_an_arc(tmp_path, mode):
    """G51.1 X0: program x is machine -x, so the program's clockwise G2 runs counter-clockwise on
    the machine (the Fanuc manual says so), still on the circle. A machine correction (1, 2) um is
    (-1, 2) um in the program: both ends of the arc shift alike, so I J stay."""
    text = ("G21 G90 G17\nG51.1 X0\nG0 X10. Y0 Z0\nG2 X0 Y-10. I-10. J0 F400\nG50.1 X0\nM30\n")
    ends, known, lines = _corrected(tmp_path, text, "fanuc", _constant([0.001, 0.002, 0]))
    assert known.all()
    arc = ends[1:]
    np.testing.assert_allclose(np.hypot(arc[:, 0], arc[:, 1]), 10, rtol=0, atol=1e-12)
    angle = np.unwrap(np.arctan2(arc[:, 1], arc[:, 0]))
    assert np.all(np.diff(angle) > 0) and arc[-1, 1] == pytest.approx(-10, abs=1e-12)
    assert np.all(arc[:, 0] <= 1e-12) and ends[0, 0] == -10
    assert lines[2:4] == ["G0 X9.9990 Y0.0020 Z0", "G2 X-0.0010 Y-9.9980 I-10. J0 F400"]


def test_haas_g101_mirrors_about_the_work_zero(tmp_path, mode):
    text = "G21 G90\nG101 Y0\nG0 X1. Y3. Z0\nG100 Y0\nG0 Y4.\nM30\n"
    ends, known, lines = _corrected(tmp_path, text, "haas", _constant([0, 0.001, 0]))
    np.testing.assert_allclose(ends[0], [1, -3, 0], rtol=0, atol=0)
    assert lines[2] == "G0 X1. Y2.9990 Z0" and lines[4] == "G0 Y4.0010"


def test_uniform_scaling_divides_the_correction(tmp_path, mode):
    """G51 X0 Y0 Z0 P2.: program 5 is machine 10; a machine correction of 2 um is 1 um written."""
    text = "G21 G90\nG51 X0 Y0 Z0 P2.\nG0 X5. Y1. Z1.\nG50\nM30\n"
    ends, _known, lines = _corrected(tmp_path, text, "fanuc", _constant([0.002, 0, 0]))
    np.testing.assert_allclose(ends, [[10, 2, 2]], rtol=0, atol=0)
    assert lines[2] == "G0 X5.0010 Y1. Z1."


def test_after_g68_an_axis_the_program_has_not_named_is_never_written(tmp_path, mode):
    """The in-plane axes are unknown after G68 until named (Fanuc: an incremental move after G68
    turns about the position G68 was given at): a block naming X alone gets no correction and no
    Y word."""
    text = "G21 G90\nG0 X1. Y1. Z1.\nG68 X0 Y0 R90.\nG1 X2. F100\nG1 Y3.\nG69\nM30\n"
    _ends, known, lines = _corrected(tmp_path, text, "fanuc", _constant([0.001, 0.001, 0.001]))
    assert known[1].tolist() == [True, False, True] and known[2].all()
    assert lines[3] == "G1 X2. Z1.0000 F100"        # Z back to its own value; no Y
    assert lines[4] == "G1 Y2.9990 X2.0010 Z1.0010"


# ----------------------------------------------------------- the second formulation: flat by hand
def _replay(lines):
    """An independent interpreter of the frame codes (absolute G0-G3 moves with X Y Z I J; G52,
    G68/G69, G51.1/G50.1, G51 P/G50 about the given centre): (machine end points, machine arc
    centres (None for a line)) of each motion line, and the G2/G3 sense on the machine."""
    pos = {"X": 0.0, "Y": 0.0, "Z": 0.0}
    shift = np.zeros(3)
    rot = None                         # (angle rad, cx, cy)
    mirror = {}                        # axis -> mirror line
    scale = None                       # (factor, centre (3,))
    motion = None
    out = []

    def place(p):
        q = np.array(p, float)
        for k, a in enumerate("XYZ"):
            if a in mirror:
                q[k] = 2 * mirror[a] - q[k]
        if scale is not None:
            q = scale[1] + scale[0] * (q - scale[1])
        if rot is not None:
            a, cx, cy = rot
            x, y = q[0] - cx, q[1] - cy
            q[0], q[1] = cx + math.cos(a) * x - math.sin(a) * y, cy + math.sin(a) * x + math.cos(a) * y
        return q + shift

    for text in lines:
        words = dict((m.group(1), float(m.group(2)))
                     for m in re.finditer(r"([A-Z])([-+]?\d*\.?\d*)", text) if m.group(1) != "G")
        gs = [float(g) for g in re.findall(r"G([\d.]+)", text)]
        if 52 in gs:
            shift = np.array([words.get(a, 0.0) for a in "XYZ"])
            continue
        if 68 in gs:
            rot = (math.radians(words["R"]), words["X"], words["Y"])
            continue
        if 51.1 in gs:
            mirror.update({a: words[a] for a in "XYZ" if a in words})
            continue
        if 51 in gs:
            scale = (words["P"], np.array([words[a] for a in "XYZ"]))
            continue
        if 69 in gs or 50 in gs or 50.1 in gs:
            rot = None if 69 in gs else rot
            scale = None if 50 in gs else scale
            mirror = {} if 50.1 in gs else mirror
            continue
        motion = next((int(g) for g in gs if g in (0, 1, 2, 3)), motion)
        if not any(a in words for a in "XYZ"):
            continue
        start = [pos[a] for a in "XYZ"]
        pos.update({a: words[a] for a in "XYZ" if a in words})
        end = place([pos[a] for a in "XYZ"])
        centre = None
        if motion in (2, 3):
            centre = place([start[0] + words.get("I", 0.0), start[1] + words.get("J", 0.0),
                            start[2]])[:2]
        out.append((end, centre))
    return out


#: a part with an arc, every word with 6 decimals (the output keeps them)
PART = ("G0 X10.000000 Y5.000000 Z2.000000\nG1 Z-1.000000 F600\nG1 X40.000000\n"
        "G2 X60.000000 Y25.000000 I0.000000 J20.000000\nG1 Y45.000000\nG3 X40.000000 Y65.000000 "
        "I-20.000000 J0.000000\nG1 X10.000000\nG0 Z5.000000\n")


def _flat(frame_lines, part, placer):
    """The part written flat: each motion line's words placed by hand, G2/G3 swapped where the
    map turns the plane over."""
    out = []
    pos = [0.0, 0.0, 0.0]
    for text in part.splitlines():
        words = dict((m.group(1), float(m.group(2))) for m in re.finditer(r"([XYZIJ])([-+\d.]+)", text))
        start = list(pos)
        for k, a in enumerate("XYZ"):
            if a in words:
                pos[k] = words[a]
        q, flip = placer(pos)
        g = re.match(r"G(\d)", text).group(1)
        if g in "23" and flip:
            g = "3" if g == "2" else "2"
        line = f"G{g} X{q[0]:.6f} Y{q[1]:.6f} Z{q[2]:.6f}"
        if "I" in words:
            c, _ = placer([start[0] + words["I"], start[1] + words["J"], start[2]])
            s, _ = placer(start)
            line += f" I{c[0] - s[0]:.6f} J{c[1] - s[1]:.6f}"
        if "F" in text:
            line += " F600"
        out.append(line)
    return "\n".join(out) + "\n"


def _rot30(p):
    a = math.radians(30.0)
    x, y = p[0] - 5.0, p[1] + 3.0
    return [5.0 + math.cos(a) * x - math.sin(a) * y, -3.0 + math.sin(a) * x + math.cos(a) * y,
            p[2]], False


CASES = {
    "G68": ("fanuc", "G68 X5.000000 Y-3.000000 R30.\n", "G69\n", _rot30),
    "G51.1": ("fanuc", "G51.1 X7.000000\n", "G50.1 X0\n", lambda p: ([14.0 - p[0], p[1], p[2]], True)),
    "G51": ("fanuc", "G51 X1.000000 Y2.000000 Z0.000000 P2.\n", "G50\n",
            lambda p: ([1 + 2 * (p[0] - 1), 2 + 2 * (p[1] - 2), 2 * p[2]], False)),
    "G52": ("linuxcnc", "G52 X100.000000 Y50.000000\n", "G52 X0 Y0\n",
            lambda p: ([p[0] + 100, p[1] + 50, p[2]], False)),
}


def programs_of(code: str) -> dict:
    """{'frame': the part under the frame change ``code``, 'flat': the same motion written flat}."""
    _dialect, on, off, placer = CASES[code]
    return {"frame": "G21 G90 G17\n" + on + PART + off + "M30\n",
            "flat": "G21 G90 G17\n" + _flat(on, PART, placer) + "M30\n"}


def compensated_both(tmp_path, capsys, code: str, scale: float, more=()):
    """[(name, text, program, output, model)] of both programs of :func:`programs_of` compensated
    with one model of the given scale (seeded), no subdivision."""
    dialect = CASES[code][0]
    _machine, _fitted, model = _model(tmp_path, "xfyz", seed=8, scale=scale)
    out_list = []
    for name, text in programs_of(code).items():
        prog, out = tmp_path / f"{name}.nc", tmp_path / f"{name}.out.nc"
        prog.write_text(text)
        code_, _o, err = _run(["compensate", "xfyz", str(model), str(prog), "-o", str(out),
                               "--dialect", dialect, "--subdivide-tol-um", "0", "--quiet", *more],
                              capsys)
        assert code_ == 0, err
        out_list.append((name, text, prog, out, model))
    return out_list


@pytest.mark.parametrize("code", list(CASES))
def test_compensated_under_the_frame_is_the_flat_program_compensated(tmp_path, capsys, code):
    """The same machine moves, once under the frame change and once written flat by hand: the
    planner sees the same machine positions, so both outputs, replayed on the machine by the
    interpreter above, put every end point and arc centre at the same place (to the 6 decimals
    written, times the scale)."""
    outs = {}
    for name, text, _prog, out, _model_path in compensated_both(tmp_path, capsys, code, 60.0,
                                                                ["--chord-tol-um", "30"]):
        outs[name] = _replay(out.read_text().splitlines())
        moved = [e for e, _c in outs[name]][:8]
        nominal = [e for e, _c in _replay(text.splitlines())]
        assert np.abs(np.array(moved) - np.array(nominal)).max() > 1e-3     # corrected (um)
    frame, flat = outs["frame"], outs["flat"]
    assert len(frame) == len(flat) >= 8
    tol = 2e-6 * (2 if code == "G51" else 1)
    for (e1, c1), (e2, c2) in zip(frame, flat):
        np.testing.assert_allclose(e1, e2, rtol=0, atol=tol)
        assert (c1 is None) == (c2 is None)
        # under scaling the writer's arc tolerance holds in the program's frame (P times larger
        # on the machine), so it may keep another centre within it: the ends are compared
        if c1 is not None and code != "G51":
            np.testing.assert_allclose(c1, c2, rtol=0, atol=tol)


# ------------------------------------------------------------------------------------- refusals
@pytest.mark.parametrize("dialect, line, words", [
    ("linuxcnc", "G68 X0 Y0 R30.", ["G68 (coordinate rotation)", "linuxcnc"]),
    ("grbl", "G52 X10.", ["G52", "grbl"]),
    ("haas", "G52 X10.", ["G52", "Setting 33"]),
    ("haas", "G51.1 X0", ["G51.1", "haas"]),
    ("fanuc", "G101 X0", ["G101", "fanuc"]),
    ("generic", "G51 X0 Y0 Z0 P2.", ["G51 (scaling)", "generic"]),
    ("fanuc", "G18 G68 X0 Z0 R30.", ["plane G18"]),
    ("fanuc", "G68 X0 Y0", ["without R"]),
    ("fanuc", "G91 G68 X0 Y0 R30.", ["under G91"]),
    ("fanuc", "G68 X0 R30.", ["centre on X only"]),
    ("fanuc", "G68 X0 Y0 I0 J0 K1 R30.", ["three-dimensional"]),
    ("fanuc", "G51 X0 Y0 Z0 P2000", ["without a decimal point"]),
    ("fanuc", "G51 X0 Y0 Z0 I2. J1. K1.\nG2 X5. Y0 I2.5 J0", ["unequal scales"]),
    ("fanuc", "G51 X0 Y0 Z0 P2.\nG68 X0 Y0 R30.", ["G68 while scaling"]),
    ("fanuc", "G68 X0 Y0 R30.\nG51.1 X0", ["G51.1 while G68"]),
    ("fanuc", "G68 X0 Y0 R30.\nG52 X5.", ["G52 while G68"]),
    ("linuxcnc", "G91 G52 X5.", ["G52 under G91"]),
    ("fanuc", "G52 X5.\nG55", ["change of work system"]),
    ("fanuc", "G68 X0 Y0 R30.\nG19", ["plane change"]),
    ("haas", "G101 X5.", ["mirrors about the work zero"]),
    ("fanuc", "G51 X0 Y0 Z0 P2.\nG81 X1. Y1. Z-1. R1. F100", ["drilling cycle G81 under scaling"]),
    ("linuxcnc", "G1 G52 X5.", ["and a move in one block"]),
])
def test_refusals_name_the_line_and_the_construct(tmp_path, capsys, dialect, line, words):
    _, _, model = _model(tmp_path, "xfyz", seed=5)
    p, out = tmp_path / "p.nc", tmp_path / "out.nc"
    p.write_text(f"G21 G90 G17\nG0 X0 Y0 Z5.\n{line}\nG1 X1. Y10. F100\nM30\n")
    code, _o, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(out), "--quiet",
                          "--dialect", dialect], capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert re.search(r"p\.nc:[345]:", lines[0]) and all(w in lines[0] for w in words), lines[0]
    assert not out.exists()


def test_g52_on_linuxcnc_survives_a_work_system_change(tmp_path, mode):
    """LinuxCNC's G52 shares G92's offsets, which apply in every work system; G92.1 cancels it."""
    text = "G21 G90 G54\nG52 X10.\nG55\nG0 X1. Y0 Z0\nG92.1\nG0 X1. Y0 Z0\nM30\n"
    ends, _known, _lines = _corrected(tmp_path, text, "linuxcnc", _constant([0, 0, 0]))
    np.testing.assert_allclose(ends[:, 0], [11, 1], rtol=0, atol=0)


def test_a_cut_program_under_a_frame_change_is_refused(tmp_path):
    from mtcomp.toolpaths.cutter import read_cut_program
    p = tmp_path / "cut.nc"
    p.write_text("O1000\nG21 G90\nG52 X5.\nG0 X0 Y0 Z1.\nG1 Z0 F100\nM30\n")    # a Fanuc's
    with pytest.raises(InputError) as exc:
        read_cut_program(p, XFYZ)
    assert exc.value.line == 4 and "G52" in exc.value.message


def test_frame_code_fields_read_back():
    """Every field of a frame code reads back as it was packed, at the ends of its range and in
    an int32 array as the reader stores them (the field readers use bit operations)."""
    from mtcomp.toolpaths import words as w
    cases = [(wcs, tool, tcp, oset, local, dwo)
             for wcs in (0, 5, 15) for tool in (0, 1, w.NO_LENGTH)
             for tcp in (False, True) for oset in (0, 1, w.MAX_OFFSET_SETS)
             for local in (False, True) for dwo in (False, True)]
    codes = np.array([w.frame_code(wcs, tool, tcp, oset, local, dwo)
                      for wcs, tool, tcp, oset, local, dwo in cases], np.int32)
    assert codes.max() < 2 ** 31
    want = np.array(cases, np.int64)
    for k, read in enumerate((w.frame_wcs, w.frame_tool, w.frame_tcp, w.frame_offset_set,
                              w.frame_local, w.frame_dwo)):
        assert np.array_equal(np.asarray(read(codes), np.int64), want[:, k]), read.__name__
        assert [int(read(int(c))) for c in codes[:8]] == want[:8, k].tolist()
