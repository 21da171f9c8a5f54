"""Haas 5-axis programs: tool centre point control G234 ... G49 and the dynamic work offset G254 ...
G255 (Haas mill operator's manual, "G234 Tool Center Point Control (TCPC)", "G254 Dynamic Work
Offset (DWO)"), on a Haas UMC-style trunnion (CAFXYZ: a C table on an A trunnion).

The oracle is the trunnion's kinematics written here by hand (textbook forward kinematics of a
tilting rotary table, checked against the independent truth machine of tests/truth, which shares
no code with mtcomp), and a replay of the hand-written programs that knows only the manual's rules:
under G234 the words are the tip in the part frame (which turns with the table), under G254 the
words run along the machine's axes from the part origin turned with the table."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths.reader import read_program
from truth.machine import TruthMachine

DATA = Path(__file__).parent / "data" / "haas"
TCPC = DATA / "umc_tcpc_g234.nc"
DWO = DATA / "umc_dwo_g254.nc"
#: the part origin (G54) as a tip position with A and C at zero (mm)
G54 = np.array([15.0, -10.0, 25.0])
G54_FLAG = "G54=X15,Y-10,Z25"
# cafxyz's rotary axis lines (the machine rotary zero point): A along X through PA, C along Z
# through PC (mtcomp/machines/cafxyz.toml, read here as numbers)
PA, PC = np.array([0.0, 0.0, -100.0]), np.zeros(3)


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _placed(p, a, c):
    """Where the part's point p (its position with A = C = 0) stands with the table at A a, C c
    (rad): turned by C about its line, then the C table by A about A's line (the trunnion carries
    C); the tool tip must stand there. Textbook forward kinematics of a tilting rotary table."""
    return _rx(a) @ (_rz(c) @ (p - PC) + PC - PA) + PA


def test_the_hand_kinematics_are_the_truths():
    """The oracle's kinematics agree with the truth machine's nominal tip (a guard on the oracle)."""
    truth = TruthMachine.zero("cafxyz")
    rng = np.random.default_rng(7)
    for _ in range(5):
        p, (a, c) = rng.uniform(-80, 80, 3), rng.uniform(-1.5, 1.5, 2)
        lin = _placed(p, a, c)
        tip = truth.nominal_pose(np.array([[*lin, a, c]]))[0][0]
        np.testing.assert_allclose(tip, p, rtol=0, atol=1e-9)


def _moves(text: str):
    """[(line, mode, {axis: value})] of each motion line whose every axis is known: mode 'tcp'
    (G234 in force), 'dwo' (G254) or 'plain'; the words (mm, deg) modal. The programs here are
    absolute, in mm, one motion per line; a switch of G234 or G254 forgets X Y Z (A and C too for
    G234), G53 lines and tool changes leave Z unknown."""
    pos, mode, out = dict.fromkeys("XYZAC"), "plain", []
    for k, raw in enumerate(text.splitlines(), 1):
        code = re.sub(r"\(.*?\)", "", raw).upper()
        words = dict(re.findall(r"([A-Z])\s*([-+]?\d*\.?\d*)", code))
        gs = {float(v) for a, v in re.findall(r"(G)\s*(\d+\.?\d*)", code)}
        if 234 in gs:
            mode, pos = "tcp", dict.fromkeys("XYZAC")
        if 254 in gs or 255 in gs:
            mode = "dwo" if 254 in gs else "plain"
            pos.update(dict.fromkeys("XYZ"))
        if 49 in gs and mode == "tcp":
            mode, pos = "plain", dict.fromkeys("XYZAC")
        if 53 in gs or "M" in words and float(words["M"]) == 6:
            pos["Z"] = None
            continue
        given = {a: float(v) for a, v in words.items() if a in "XYZAC"}
        if not given:
            continue
        pos.update(given)
        if all(v is not None for v in pos.values()):
            out.append((k, mode, dict(pos)))
    return out


def _axes(moves) -> np.ndarray:
    """(n, 5) X Y Z (mm) A C (rad): the axes the control reaches for each move, by the manual's
    rules and the hand kinematics (G54 the part origin)."""
    q = []
    for _line, mode, w in moves:
        a, c = np.radians(w["A"]), np.radians(w["C"])
        xyz = np.array([w["X"], w["Y"], w["Z"]])
        lin = (_placed(G54 + xyz, a, c) if mode == "tcp" else
               _placed(G54, a, c) + xyz if mode == "dwo" else G54 + xyz)
        q.append([*lin, a, c])
    return np.array(q)


def tip_errors_um(truth: TruthMachine, model: Path, tmp_path: Path) -> dict:
    """{program: (before, after)} rms tip error (um) on the truth machine of each Haas program and
    of its compensation with ``model`` (relative to the part origin's error as probed, A = C = 0):
    the programs' words turned into axes by :func:`_axes`, the truth's nominal tip at the source's
    axes the aim."""
    datum = np.array([[*G54, 0.0, 0.0]])
    err_datum = truth.true_pose(datum)[0] - truth.nominal_pose(datum)[0]
    out = {}
    for src in (TCPC, DWO):
        dst = tmp_path / src.name
        assert main(["compensate", "cafxyz", str(model), str(src), "-o", str(dst), "--quiet",
                     "--work-offset", G54_FLAG, "--max-correction-um", "200",
                     "--max-step-um", "200", "--max-correction-urad", "2000"]) == 0
        a, b = _moves(src.read_text()), _moves(dst.read_text())
        assert len(a) >= 10 and len(b) >= len(a)
        # each source move's end and the output move (of its mode) ending nearest to it: the
        # correction is um, the moves mm apart; a block the planner split ends where its last
        # piece does
        near = [min((m for m in b if m[1] == mode),
                    key=lambda m: sum((m[2][k] - w[k]) ** 2 for k in "XYZAC")) for _k, mode, w in a]
        q_src, q_out = _axes(a), _axes(near)
        aim = truth.nominal_pose(q_src)[0]
        rms = [1e3 * float(np.sqrt(np.mean(np.sum((truth.true_pose(q)[0] - aim - err_datum) ** 2,
                                                  axis=1)))) for q in (q_src, q_out)]
        out[src.name] = tuple(rms)
    return out


# ------------------------------------------------------------------- reading and writing (cheap)
@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    from mtcomp.models import save_model
    from test_export_formats import random_model
    path = tmp_path_factory.mktemp("haas") / "model.json"
    save_model(path, random_model("cafxyz", (), 3, 3.0, None))
    return path


_WORD = re.compile(r"([XYZAC])(-?\d*\.?\d*)")


@pytest.mark.parametrize("program", [TCPC, DWO], ids=["G234", "G254"])
def test_only_the_corrected_words_change(program, model_file, tmp_path, capsys):
    """The output keeps G234/G254 and every other word; only axis words change (by the correction,
    um) or are added where the program had given the axis; under G254 no rotary word is added or
    changed (the manual asks for G255 before any rotary motion), nor on a line whose axes are not
    all given yet. The summary names the machine rotary zero point the machine file gives."""
    out = tmp_path / program.name
    assert main(["compensate", "cafxyz", str(model_file), str(program), "-o", str(out),
                 "--work-offset", G54_FLAG]) == 0
    said = capsys.readouterr().out
    assert "MRZP" in said and "A through (0, 0, -100) mm, C through (0, 0, 0) mm" in said
    src, dst = program.read_text().splitlines(), out.read_text().splitlines()
    assert len(src) == len(dst)
    complete = {k for k, _mode, _w in _moves(program.read_text())}
    under_dwo = {k for k, mode, _w in _moves(program.read_text()) if mode == "dwo"}
    changed = 0
    last_in, last_out = {}, {}          # each rotary axis's last value in the input, the output
    for k, (a, b) in enumerate(zip(src, dst), 1):
        assert _WORD.sub("", a).split() == _WORD.sub("", b).split(), (k, a, b)
        wa, wb = dict(_WORD.findall(a)), dict(_WORD.findall(b))
        standing_in, standing_out = dict(last_in), dict(last_out)
        last_in.update({x: float(v) for x, v in wa.items() if x in "AC" and v.strip(".-")})
        last_out.update({x: float(v) for x, v in wb.items() if x in "AC" and v.strip(".-")})
        if a == b:
            continue
        changed += 1
        if k not in complete:
            # a line whose axes are not all known changes only a rotary word it names, for an axis
            # that does not move: it stands with the correction written before (planner._links,
            # the standing rule), which the line's own word would take away
            for axis in (x for x in wb if wa.get(x) != wb[x]):
                assert axis in "AC" and axis in wa, (k, a, b)
                assert float(wa[axis]) == standing_in.get(axis), (k, a, b)
                assert float(wb[axis]) == standing_out.get(axis), (k, a, b)
            continue
        assert set(wa) <= set(wb)
        for axis, v in wb.items():
            old = float(wa[axis]) if axis in wa else None
            if old is not None:
                assert abs(float(v) - old) < 0.02, (k, a, b)
            if k in under_dwo:
                assert axis not in "AC" or wa.get(axis) == v, (k, a, b)
    assert changed >= 8
    assert ("G234" in out.read_text()) == ("G234" in program.read_text())
    assert out.read_text().count("G254") == program.read_text().count("G254")


# ----------------------------------------------------------------------------- refused, one line
HEAD = "%\nO01003 (HAAS)\nG00 G17 G21 G40 G49 G80 G90\nG54\nT1 M06\n"


@pytest.mark.parametrize("body, line, says", [
    ("G00 A30. C45.\nG254\nG00 X1. Y2.\nG01 A35.\n", 9, "rotary motion (A) under G254"),
    ("G254\nG00 X1. Y2.\n", 6, "G254 before the program positioned A, C"),
    ("G00 A30. C45.\nG254\nG28 G91 Z0.\n", 8, "G28 under G254"),
    ("G00 A30. C45.\nG254\nG55\n", 8, "a change of work system under G254"),
    ("G00 A30. C45.\nG254 X1.\n", 7, "G254 with axis words"),
    ("G00 A0. C0.\nG00 G234 X20. Y0. Z30. H01\nG02 X30. Y10. R10. F500.\n", 8,
     "an arc (G02/G03) in tool centre point mode (G234)"),
    ("G41 D01\nG00 G234 X20. Y0. Z30. H01\n", 7, "G234 under cutter radius compensation"),
    ("G00 G234 X20. Y0. Z30. H01\nG91 G01 X1. F500.\n", 7, "G91 (incremental positions) in tool"),
    ("G00 G234 X20. Y0. Z30. H01\nG28 G91 Z0.\n", 7, "G28 in tool centre point mode (G234)"),
    ("G00 A30. C45.\nG254\nG00 G234 X1. Y2. Z3. H01\n", 8, "G234 while G254"),
])
def test_what_is_not_sure_is_refused_naming_the_line(body, line, says, tmp_path):
    path = tmp_path / "p.nc"
    path.write_text(HEAD + body + "M30\n%\n")
    with pytest.raises(InputError, match=re.escape(says)) as err:
        read_program(path, load_machine("cafxyz"), dialect="haas")
    assert err.value.line == line


def test_a_refusal_exits_2_and_writes_nothing(model_file, tmp_path, capsys):
    path, out = tmp_path / "p.nc", tmp_path / "out.nc"
    path.write_text(HEAD + "G00 A30. C45.\nG254\nG00 X1. Y2.\nG00 C50.\nM30\n%\n")
    assert main(["compensate", "cafxyz", str(model_file), str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "p.nc:9:" in err[0] and "G254" in err[0] and "Traceback" not in err[0]
    assert not out.exists()


def test_the_haas_codes_on_another_dialect_are_refused(tmp_path):
    path = tmp_path / "p.nc"
    path.write_text("G21 G90\nG00 A0 C0\nG254\nM30\n")
    with pytest.raises(InputError, match="G254 .*give --dialect haas"):
        read_program(path, load_machine("cafxyz"), dialect="fanuc")


def test_the_axes_and_the_datum_are_the_hand_kinematics():
    """Each complete move of both programs is placed at the axes the hand kinematics give (under
    G234 the tip turned with the table, under G254 the part origin turned with it plus X Y Z along
    the machine's axes), and its datum is the part origin as probed, A and C at zero: the reference
    of the correction (a G254 datum at the turned origin with A and C at zero left 6.4 um on the
    truth machine, against 3.1)."""
    from mtcomp.toolpaths.gcode import iter_segment_chunks
    from mtcomp.toolpaths.offsets import ProgramSetup
    machine = load_machine("cafxyz")
    setup = ProgramSetup(machine, work_offsets={0: np.array([*G54, 0.0, 0.0])})
    for program in (TCPC, DWO):
        placed = [setup.apply(c)[0] for c in iter_segment_chunks(program, machine, dialect="haas")]
        end = np.concatenate([p.end for p in placed])
        datum = np.concatenate([p.datum for p in placed])
        line = np.concatenate([p.line for p in placed])
        moves = _moves(program.read_text())
        rows = [int(np.flatnonzero(line == k)[-1]) for k, _mode, _w in moves]
        np.testing.assert_allclose(end[rows], _axes(moves), rtol=0, atol=1e-9)
        np.testing.assert_allclose(datum[rows], np.tile([*G54, 0.0, 0.0], (len(rows), 1)),
                                   rtol=0, atol=1e-9)
