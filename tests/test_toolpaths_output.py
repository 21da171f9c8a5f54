"""The corrected program differs from its input only by the correction.

Oracles written here, sharing no code with mtcomp:

* a tokenizer of G-code lines (words with their spelling, blanks, comments) and a comparison of an
  input line with its output line: only the numbers of axis words (X Y Z A B C) and arc centre
  words (I J K R) may change, each written with at least its input decimals and at least 4 (5 in
  inch); axis words may be added right after the line's last axis word, in the line's letter case
  (that of its first axis word, else of its first word);
  a G91 may be dropped and G90 or a motion word put in front; nothing else (word order, case,
  spacing, comments, N numbers, G00 vs G0) changes;
* a replay of G0-G3 programs (its own arc interpolation from I J K or R) that gives the tool path
  densely, against which the written arcs are checked: every point of the intended corrected path
  (the nominal arc plus the correction, or the planner's corrected points put back on the arc) lies
  within the chord tolerance of the written path, and arcs stay arcs.

Hand-written lines have outputs derived by hand; every accepted program of tests/data/gcode_corpus
is checked line by line; the compiled and the pure-Python writer give the same bytes.
"""
import difflib
import math
import re

import numpy as np
import pytest
from scipy.spatial import cKDTree

from mtcomp import load_machine
from mtcomp.cli import main
from mtcomp.toolpaths import _fast, iter_segment_chunks, write_corrected
from replay_sinumerik import is_sinumerik
from test_gcode_corpus import (DIALECTS, PROGRAMS, REFUSED, _machine_file, _model_file, _topology,
                               program_machine_file, source_bytes)

XFYZ = load_machine("xfyz")
CHORD_TOL_MM = 1e-3
#: 4-decimal rounding of three axes and of the centre: what the written arc may add to its fit
ROUNDING_MM = 2e-4

_TOKEN = re.compile(r"(?P<blank>[ \t]+)|(?P<comment>\([^)]*\)|;.*)"
                    r"|(?P<letter>[A-Za-z])(?P<num>[ \t]*[-+]?[ \t]*(?:\d[\d \t]*\.?[\d \t]*|\.[\d \t]+))"
                    r"|(?P<other>.)")
AXES, CENTRE = "XYZABC", "IJKR"


def tokens(line: str) -> list[tuple]:
    """('w', letter as written, number as written) / ('b', blanks) / ('c', comment) / ('o', char)."""
    out = []
    for m in _TOKEN.finditer(line):
        if m.group("letter"):
            num = m.group("num").rstrip(" \t")
            out.append(("w", m.group("letter"), num.strip(" \t")))
            if len(num) < len(m.group("num")):
                out.append(("b", m.group("num")[len(num):]))
        elif m.group("blank"):
            out.append(("b", m.group(0)))
        elif m.group("comment"):
            out.append(("c", m.group(0)))
        else:
            out.append(("o", m.group(0)))
    return out


def value(t) -> float:
    return float(t[2].replace(" ", "").replace("\t", ""))


def decimals(t) -> int:
    num = t[2].replace(" ", "")
    return len(num) - num.index(".") - 1 if "." in num else 0


def _key(t):
    if t[0] == "w" and t[1].upper() in AXES + CENTRE:
        return ("w", t[1])
    return t


def check_line(src: str, out: str, inch: bool = False) -> None:
    """out differs from src only as the module docstring says (AssertionError otherwise)."""
    a, b = tokens(src), tokens(out)
    words_a = [i for i, t in enumerate(a) if t[0] == "w"]
    axis_a = [i for i in words_a if a[i][1].upper() in AXES]
    centre_a = [i for i in words_a if a[i][1].upper() in AXES + CENTRE]
    lower = bool(words_a) and a[(axis_a or words_a)[0]][1].islower()
    n_word = [i for i in words_a if a[i][1].upper() == "N"]
    head_at = {0, n_word[0] + 1} if n_word else {0, words_a[0] if words_a else 0}
    ops = difflib.SequenceMatcher(None, [_key(t) for t in a], [_key(t) for t in b],
                                  autojunk=False).get_opcodes()
    if not centre_a:          # no motion line: as written
        assert src == out, (src, out)
    for tag, i1, i2, j1, j2 in ops:
        if tag == "equal":
            for ta, tb in zip(a[i1:i2], b[j1:j2]):
                if ta != tb:          # a corrected number: at least its decimals, and 4 (5)
                    base = 5 if inch and ta[1].upper() not in "ABC" else 4
                    assert decimals(tb) >= max(decimals(ta), base), (src, out, ta, tb)
            continue
        # blanks go and come only with the words dropped or added
        for part in (a[i1:i2], b[j1:j2]):
            assert all(t[0] != "b" for t in part) or any(t[0] == "w" for t in part), (src, out)
        assert all(t[0] == "b" or (t[0] == "w" and t[1].upper() == "G" and value(t) == 91)
                   or (t[0] == "w" and t[1].upper() == "R") for t in a[i1:i2]), (src, out, a[i1:i2])
        for t in b[j1:j2]:
            if t[0] == "b":
                continue
            assert t[0] == "w", (src, out, t)
            letter = t[1].upper()
            if letter == "G":
                assert value(t) in (0, 1, 2, 3, 90) and i1 in head_at | {i + 1 for i in head_at} \
                    or any(u[1].upper() == "G" for u in a[i1:i2]), (src, out, t)
            elif letter in AXES:
                # after the line's last axis word (a blank may sit between), in the line's case
                last = axis_a[-1] if axis_a else -1
                assert i1 in (last + 1, last + 2) or not axis_a, (src, out, t)
                assert t[1].islower() == lower, (src, out, t)
            else:
                assert letter in CENTRE, (src, out, t)
                last = centre_a[-1] if centre_a else -1
                assert i1 in (last + 1, last + 2) or any(u[1].upper() == "R" for u in a[i1:i2] if
                                                         u[0] == "w"), (src, out, t)


def _after_expansion_header(text: str) -> str:
    """``text`` without its first lines that are mtcomp's notes of an expansion (each names the
    file it expanded)."""
    while text.startswith("(expanded by mtcomp from "):
        text = text.partition("\n")[2]
    return text


def _piece_line(line: str) -> bool:
    """A line the writer adds: a later piece of a split block (axis, centre, motion and F words) or
    a G91 before a line that relies on it."""
    ws = [t for t in tokens(line) if t[0] != "b"]
    return bool(ws) and all(t[0] == "w" and (t[1].upper() in AXES + CENTRE + "F" or (
        t[1].upper() == "G" and value(t) in (0, 1, 2, 3, 91))) for t in ws)


def _lines(text):
    """Lines split at LF only (a program's latin-1 text may hold other characters str.splitlines
    splits at), without their CR."""
    lines = [ln[:-1] if ln.endswith("\r") else ln for ln in text.split("\n")]
    return lines[:-1] if lines and lines[-1] == "" else lines


def check_program(src_text: str, out_text: str) -> None:
    """Every input line has its output line (in order) that differs only by the correction; the
    output lines in between are pieces the writer adds."""
    src, out = _lines(src_text), _lines(out_text)
    j = 0
    inch = False
    for line in src:
        code = re.sub(r"\([^)]*\)|;.*", "", line).upper().replace(" ", "")
        while True:
            assert j < len(out), f"input line {line!r} has no output line"
            try:
                check_line(line, out[j], inch)
                break
            except AssertionError:
                assert _piece_line(out[j]), (line, out[j])
                j += 1
        j += 1
        if re.search(r"G20(?!\d)", code):
            inch = True
        elif re.search(r"G21(?!\d)", code):
            inch = False
    assert all(_piece_line(x) for x in out[j:])


# ------------------------------------------------------------------------------ hand-written
def _field(p):
    """A correction field (mm) of the positions p (n, 3): X and Y corrections grow with Z, the Z
    correction with X."""
    return np.stack([1e-4 * p[:, 2], -2e-4 * p[:, 2], 3e-4 * p[:, 0]], axis=1)


def _write_with(tmp_path, text, machine=XFYZ, field=_field, nodes=False, planner=False, **kw):
    """Write text corrected by field at every segment end (known axes only); nodes: also a node
    at the middle of every arc chord, on the chord, corrected by the field there; planner: as the
    planner corrects, no row with an axis not known (an arc passed through from a position not
    given must start where the output stands uncorrected: the writer refuses it otherwise)."""
    p = tmp_path / "in.nc"
    p.write_bytes(text.encode("latin-1"))

    xyz = [machine.axis_names.index(a) for a in "XYZ"]

    def shift(q, known):
        d = np.zeros_like(q)
        d[xyz] = field(q[None, xyz])[0]
        return q + np.where(known & (known.all() or not planner), d, 0.0)

    def corr():
        for c in iter_segment_chunks(p, machine, CHORD_TOL_MM, **kw):
            pts, counts = [], []
            for r in range(len(c)):
                end = shift(c.end[r], c.known[r])
                if nodes and c.from_arc[r]:
                    pts.append(shift(0.5 * (c.start[r] + c.end[r]), c.known[r]))
                pts.append(end)
                counts.append(2 if nodes and c.from_arc[r] else 1)
            yield c, np.array(pts), np.array(counts)
    out = tmp_path / "out.nc"
    write_corrected(p, out, machine, corr(), CHORD_TOL_MM, **kw)
    return out.read_bytes().decode("latin-1")


def _use_writer(kind: str, monkeypatch) -> bool:
    """Select the compiled or the pure-Python writer; False when the compiled one is not there."""
    if kind == "python":
        monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
        return True
    monkeypatch.delenv("MTCOMP_NO_FAST_GCODE", raising=False)
    return _fast.available()


@pytest.fixture(params=["compiled", "python"])
def gcode_path(request, monkeypatch):
    """The tests that take it run on both writers."""
    if not _use_writer(request.param, monkeypatch):
        pytest.skip("no C compiler: the compiled G-code path is not available")


def test_hand_written_lines_change_only_their_numbers(tmp_path, gcode_path):
    text = ("G90 G21\nG0 X0 Y0 Z10\nG01 z5.000000 F100 (c)\nG00 X1.123456 y2\nT1 M6\n"
            "G43 Z10. H1\nN10  G1   X1.5    Y2 ;c\nG1X1Y2\nM30\n")
    out = _write_with(tmp_path, text).splitlines()
    # by hand: field (1e-4 z, -2e-4 z, 3e-4 x) mm at each end
    assert out[1] == "G0 X0.0010 Y-0.0020 Z10"                      # Z: no correction at X0
    assert out[2] == "G01 z5.000000 x0.000500 y-0.001000 F100 (c)"   # 6 decimals, lower case
    assert out[3] == "G00 X1.123956 y1.9990 Z5.000337"
    assert out[5] == "G43 Z10.0003 X1.1245 Y1.9980 H1"
    assert out[6] == "N10  G1   X1.5010    Y1.9980 Z10.0005 ;c"
    assert out[7] == "G1X1.0010Y1.9980Z10.0003"
    check_program(text, "\n".join(out) + "\n")


def test_inch_words_keep_their_decimals(tmp_path, gcode_path):
    text = "G20 G90\nG0 X1.724638 Y0 Z0\nG1 x2.5 F10\n"
    out = _write_with(tmp_path, text, field=lambda p: np.tile([0.001, 0.0, 0.0], (len(p), 1)))
    # 0.001 mm = 0.0000394 in
    assert out.splitlines()[1:] == ["G0 X1.724677 Y0 Z0", "G1 x2.50004 F10"]


def test_the_oracle_catches_what_the_writer_must_not_do():
    check_line("G00 X1.123456 y2", "G00 X1.123956 y1.9990 Z5.000337")
    for bad in ("G0 X1.123956 y1.9990",          # G00 became G0
                "G00 X1.1240 y1.9990",           # decimals lost
                "G00 X1.123956 Y1.9990",         # case changed
                "G00 y1.9990 X1.123956",         # order changed
                "G00  X1.123956 y1.9990",        # spacing changed
                "G00 X1.123956 y1.9990 F100",    # a word added that is not an axis
                "G00 Z5.0003 X1.123956 y1.9990"):  # an axis added in front
        with pytest.raises(AssertionError):
            check_line("G00 X1.123456 y2", bad)
    with pytest.raises(AssertionError):
        check_line("G1 X1 (a)", "G1 X1.0010 (b)")
    with pytest.raises(AssertionError):
        check_line("G1 x1 F10", "G1 x1.0001 F10", inch=True)     # 4 decimals in inch


def test_full_circle_and_r_arcs_keep_their_form(tmp_path, gcode_path):
    text = "G0 X0 Y0 Z0\nG2 X10 Y0 R5 F100\nG3 I-5 J0\nG2 X0 Y0 I-5 J0\n"
    shift = lambda p: np.tile([0.001, 0.0, 0.0], (len(p), 1))      # noqa: E731
    out = _write_with(tmp_path, text, field=shift).splitlines()
    assert out == ["G0 X0.0010 Y0 Z0", "G2 X10.0010 Y0 R5 F100", "G3 I-5 J0", "G2 X0.0010 Y0 I-5 J0"]


# ------------------------------------------------------------------------------------- arcs
#: plane -> (first in-plane column, second, normal, offset letter of the first, of the second)
PLANES = {17: (0, 1, 2, "I", "J"), 18: (2, 0, 1, "K", "I"), 19: (1, 2, 0, "J", "K")}
ARC_PROGRAM = ("G21 G90 G17\nG0 X0 Y0 Z0\nG1 X10 Y0 F100\nG2 X30 Y0 I10 J0\nG3 X50 Y0 R10\n"
               "G3 X50 Y0 I-10 J0 Z-2\nG18 G2 X70 Z-2 I10 K0\nG19 G3 Y20 Z-2 J10 K0\n"
               "G17 G2 X60 Y30 R-10\nG1 X0 Y0\nM30\n")


def _wavy(p):
    """A correction field (mm) that bends arcs: about 20 um across 10 mm."""
    return np.stack([0.02 * np.sin(p[:, 0] / 7), 0.015 * np.cos(p[:, 1] / 5),
                     0.01 * np.sin((p[:, 0] + p[:, 1]) / 9)], axis=1)


def _arc_points(start, end, words, motion, plane, step_mm):
    """Dense points of one arc (own interpolation: centre from I J K or R, radius and the other
    axes linear in the angle)."""
    a, b, _n, l0, l1 = PLANES[plane]
    s2, e2 = start[[a, b]], end[[a, b]]
    ccw = motion == 3
    if "R" in words:
        r, d = words["R"], e2 - s2
        length = math.hypot(*d)
        h = math.sqrt(max(r * r - length * length / 4, 0.0))
        side = (1 if ccw else -1) * (1 if r > 0 else -1)   # the minor arc's centre: left if CCW
        c = (s2 + e2) / 2 + side * h * np.array([-d[1], d[0]]) / length
    else:
        c = s2 + np.array([words.get(l0, 0.0), words.get(l1, 0.0)])
    a0, a1 = math.atan2(*(s2 - c)[::-1]), math.atan2(*(e2 - c)[::-1])
    if math.hypot(*(e2 - s2)) < 1e-9:
        sweep = 2 * math.pi
    else:
        sweep = ((a1 - a0) if ccw else (a0 - a1)) % (2 * math.pi) or 2 * math.pi
    r0, r1 = math.hypot(*(s2 - c)), math.hypot(*(e2 - c))
    t = np.linspace(0.0, 1.0, max(8, math.ceil(sweep * max(r0, r1) / step_mm)) + 1)
    ang = a0 + (sweep if ccw else -sweep) * t
    pts = start + np.outer(t, end - start)
    pts[:, a] = c[0] + (r0 + (r1 - r0) * t) * np.cos(ang)
    pts[:, b] = c[1] + (r0 + (r1 - r0) * t) * np.sin(ang)
    return pts, c


def replay(text, step_mm=5e-3):
    """Replay of a G0-G3 program in mm and G90: per block (line index, motion, dense points (k, 3),
    arc centre in its plane or None, plane)."""
    pos, motion, plane, blocks = np.zeros(3), None, 17, []
    for k, line in enumerate(text.splitlines()):
        words = {}
        for t in tokens(line):
            if t[0] == "w" and t[1].upper() == "G":
                g = value(t)
                motion = int(g) if g in (0, 1, 2, 3) else motion
                plane = int(g) if g in (17, 18, 19) else plane
            elif t[0] == "w":
                words[t[1].upper()] = value(t)
        if not any(c in words for c in "XYZIJKR"):
            continue
        end = pos.copy()
        for i, c in enumerate("XYZ"):
            end[i] = words.get(c, end[i])
        if motion in (2, 3):
            pts, centre = _arc_points(pos, end, words, motion, plane, step_mm)
        else:
            pts, centre = np.vstack([pos, end]), None
        blocks.append((k, motion, pts, centre, plane))
        pos = end
    return blocks


def _distance_to_path(q, paths):
    """(m,) distance of points q (m, 3) to the polylines ``paths`` (list of (k, 3)): to the
    segments next to the 4 nearest of their points."""
    pts = np.vstack(paths)
    seg_ok = np.concatenate([np.r_[np.ones(len(p) - 1, bool), False] for p in paths])
    _, near = cKDTree(pts).query(q, k=4)
    best = np.full(len(q), np.inf)
    for idx in near.T:
        for first in (idx - 1, idx):
            ok = (first >= 0) & (first < len(pts) - 1)
            f = np.where(ok, first, 0)
            ok &= seg_ok[f]
            a, ab = pts[f], pts[f + 1] - pts[f]
            t = np.sum((q - a) * ab, axis=1) / np.maximum(np.sum(ab * ab, axis=1), 1e-30)
            d = np.linalg.norm(q - (a + np.clip(t, 0, 1)[:, None] * ab), axis=1)
            best = np.where(ok, np.minimum(best, d), best)
        best = np.minimum(best, np.linalg.norm(q - pts[idx], axis=1))
    return best


def _arc_paths(blocks):
    return [pts for _k, motion, pts, _c, _p in blocks if motion in (2, 3)]


@pytest.mark.parametrize("nodes", [False, True])
def test_arcs_stay_arcs_within_the_chord_tolerance(tmp_path, gcode_path, nodes):
    out = _write_with(tmp_path, ARC_PROGRAM, field=_wavy, nodes=nodes)
    check_program(ARC_PROGRAM, out)
    src, written = replay(ARC_PROGRAM), replay(out)
    arcs_in, arcs_out = _arc_paths(src), _arc_paths(written)
    # the field bends the arcs beyond the tolerance of one arc: some are split, into arcs only
    assert len(arcs_out) > len(arcs_in) == 6
    assert sum(m == 1 for _k, m, *_ in written) == sum(m == 1 for _k, m, *_ in src)
    # the intended path: the nominal arcs plus the correction there
    intended = [p + _wavy(p) for p in arcs_in]
    tol = CHORD_TOL_MM + ROUNDING_MM
    assert _distance_to_path(np.vstack(arcs_out), intended).max() <= tol
    assert _distance_to_path(np.vstack(intended), arcs_out).max() <= tol
    # and the uncorrected arcs would miss it: the check has teeth
    assert _distance_to_path(np.vstack(arcs_in), intended).max() > 5 * tol


def test_arcs_from_the_planner_within_the_chord_tolerance(tmp_path, capsys):
    """compensate with a model: the planner's corrected points (report rows, nodes on a chord put
    back on the nominal arc by the test) lie within the chord tolerance of the written arcs."""
    prog = tmp_path / "arcs.nc"
    prog.write_text(ARC_PROGRAM)
    machine_path = _machine_file(tmp_path, "XFYZ")
    model = _model_file(tmp_path, machine_path, seed=4)
    out, rep = tmp_path / "out.nc", tmp_path / "rep.csv"
    assert main(["compensate", str(machine_path), str(model), str(prog), "-o", str(out),
                 "--report", str(rep)]) == 0, capsys.readouterr().err
    check_program(ARC_PROGRAM, out.read_text())
    rows = np.genfromtxt(rep, delimiter=",", names=True)
    src, written = replay(ARC_PROGRAM), replay(out.read_text())
    assert len(_arc_paths(written)) >= len(_arc_paths(src))
    line_of = {k + 1: (centre, plane) for k, m, _p, centre, plane in src if m in (2, 3)}
    on_arc = np.isin(rows["line"].astype(int), list(line_of))
    assert on_arc.sum() > 100
    x = np.stack([rows["x_mm"], rows["y_mm"], rows["z_mm"]], axis=1)[on_arc]
    c = np.stack([rows["cx_um"], rows["cy_um"], rows["cz_um"]], axis=1)[on_arc] * 1e-3
    nominal = x - c
    for i, line in enumerate(rows["line"][on_arc].astype(int)):
        centre, plane = line_of[line]
        a, b = PLANES[plane][:2]
        radius = math.hypot(*(np.array([_arc_start(src, line)[a], _arc_start(src, line)[b]]) - centre))
        v = nominal[i, [a, b]] - centre
        nominal[i, [a, b]] = centre + radius * v / np.linalg.norm(v)
    gap = _distance_to_path(nominal + c, _arc_paths(written))
    assert gap.max() <= CHORD_TOL_MM + ROUNDING_MM


def _arc_start(blocks, line):
    return next(p[0] for k, _m, p, _c, _pl in blocks if k + 1 == line)


# ------------------------------------------------------------------------------------- corpus
def _g23_lines(text):
    return sum(any(t[0] == "w" and t[1].upper() == "G" and value(t) in (2, 3) for t in tokens(ln))
               for ln in _lines(text))


def _small_field(p):
    return np.stack([0.005 * np.sin(p[:, 0] / 30), 0.004 * np.cos(p[:, 1] / 20),
                     0.003 * np.sin(p[:, 2] / 10)], axis=1)


# Heidenhain conversational (.h) and Sinumerik programs (known as tests/replay_sinumerik.py knows
# them: a header, a DEF, a cycle call, MSG or an R parameter set) are written in their own form, not
# G-code: they are checked by tests/test_toolpaths_heidenhain.py, test_toolpaths_sinumerik.py, the
# corpus test and their own replays
@pytest.mark.parametrize("prog", [p for p in PROGRAMS if p.name not in REFUSED and p.suffix != ".h"
                                  and not is_sinumerik(p.read_bytes())],
                         ids=lambda p: p.name)
def test_corpus_output_differs_only_by_the_correction(tmp_path, monkeypatch, prog):
    # a program with code to compute is written as its expansion (tests/test_toolpaths_ngc.py)
    text = source_bytes(prog).decode("latin-1")
    machine = load_machine(program_machine_file(tmp_path, prog, _topology(text)))
    outs = {}
    # the dialect its user gives where the program does not show it (test_gcode_corpus.DIALECTS)
    given = {"dialect": DIALECTS[prog.name]} if prog.name in DIALECTS else {}
    for kind in ("python", "compiled"):
        if _use_writer(kind, monkeypatch):
            outs[kind] = _write_with(tmp_path, text, machine, _small_field, planner=True,
                                     **given)
    out = outs["python"]
    assert all(o == out for o in outs.values())          # both writers, the same bytes
    # an expansion that still holds code (values the controller holds: fluidnc_probe.nc) is
    # expanded again, and its first line names the file it was expanded from: not compared
    text, out = (_after_expansion_header(x) for x in (text, out))
    check_program(text, out)
    assert _g23_lines(out) >= _g23_lines(text)
