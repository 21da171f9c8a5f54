"""What compensate says about a block is what it wrote there: BLOCKS.csv's ``corrected`` and
``active_bounds``, the printed summary and SUMMARY.json against the written program itself, read
back here by a few lines of its own (the words of each line, compared with the source's)."""
import csv
import json
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.models import Backlash, save_model
from test_export_formats import random_model

BL_UM = 30.0
#: X's scale error (file units of EXX_1): 6 um at X150 on the xfyz machine, relative to X0
SCALE = 40.0

# a Fanuc drilling post: the first hole where the tool change left it positioned, then two more
DRILL = ("%\nO1000\nN1 G90 G54 G0 X150. Y10.\nN2 G43 H1 Z50. M8\n"
         "N3 G98 G81 X150. Y10. Z-5. R2. F200.\nN4 X170.\nN5 X190. Y20.\nN6 G80\nN7 M30\n%\n")


def _model(tmp_path, support=None, name="model.json"):
    """A backlash of X (30 um) and a scale error of X, nothing else."""
    fm = random_model("xfyz", (Backlash("X"),), 3, 0.0, support)
    fm.params.set_file_value("BL_X", BL_UM)
    fm.params.set_file_value("EXX_1", SCALE)
    p = tmp_path / name
    save_model(p, fm)
    return p


def _compensate(tmp_path, model, text, capsys, name="p.nc"):
    prog, out = tmp_path / name, tmp_path / ("o" + name[1:])
    rep, summ = tmp_path / "B.csv", tmp_path / "S.json"
    prog.write_text(text)
    capsys.readouterr()
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--report", str(rep),
                 "--json", str(summ), "--quiet"]) == 0
    printed = capsys.readouterr().out
    with open(rep, newline="") as f:
        rows = list(csv.DictReader(f))
    return out.read_text(), rows, printed, json.loads(summ.read_text())


def _axis_words(line):
    return dict(re.findall(r"([XYZ])(-?[\d.]+)", line.upper()))


def test_a_hole_whose_x_correction_the_reversal_rule_holds_is_not_called_corrected(tmp_path,
                                                                                   capsys):
    """The first hole stands where N1 put X, coming from a position the program had not given: X's
    direction there is not known, so the rule leaves its correction where N1's was (none: N1's Z
    is not known). Its line is written as it was; the report must say so."""
    text, rows, printed, summary = _compensate(tmp_path, _model(tmp_path), DRILL, capsys)
    src, out = DRILL.splitlines(), text.splitlines()
    assert len(out) == len(src)
    by_line = {int(r["line"]): r for r in rows}
    assert sorted(by_line) == [3, 4, 5, 6, 7]
    for k, r in by_line.items():
        written_as_source = _axis_words(out[k - 1]) == _axis_words(src[k - 1])
        before = float(r["e_before_um"]) if r["e_before_um"] else 0.0
        if r["unknown_axes"]:
            assert r["corrected"] == "0" and written_as_source
            continue
        assert before > 5.0, (k, r)          # every other block asks for a correction
        # corrected = 1 exactly where the line carries a correction
        assert r["corrected"] == ("0" if written_as_source else "1"), (k, r, out[k - 1])
    # the G43 move and the first hole: held by the rule, written as the source, their error kept
    for k in (4, 5):
        r = by_line[k]
        assert out[k - 1] == src[k - 1]
        assert r["active_bounds"] == "reversal_x" and float(r["cx_um"]) == 0.0
        np.testing.assert_allclose(float(r["ex_after_um"]), float(r["ex_before_um"]), rtol=0,
                                   atol=1e-9)
        np.testing.assert_allclose(abs(float(r["ex_before_um"])), 6.0, rtol=0, atol=1e-3)
    assert out[5] != src[5] and out[6] != src[6]
    assert summary["corrected"]["blocks"] == 2
    assert summary["uncorrected"]["held_by_bounds"] == 2
    assert summary["corrected"]["max_after_um"] < 0.01 and summary["max_after_um"] > 5.9
    assert "over the 2 blocks corrected" in printed
    assert ("2 blocks not corrected on every axis: a bound held the whole correction of an axis "
            "(reversal_x 2; first at line 4;") in printed


@pytest.mark.parametrize("approach, held", [("", 2), ("N21 G0 X140. Y10.\nN22 X150.\n", 1)])
def test_the_summary_says_which_held_blocks_lacked_a_direction(tmp_path, capsys, approach, held):
    """The G43 line and the first hole are held only because X had not moved since the tool
    change (its direction not known): the summary and SUMMARY.json say how many held blocks are
    such (uncorrected.held_direction_unknown). With X moved to the hole by the program after the G43
    line (X140 then X150: +X), the hole is corrected, and only the G43 line is held so."""
    text = DRILL.replace("N3 G98", approach + "N3 G98")
    _text, rows, printed, summary = _compensate(tmp_path, _model(tmp_path), text, capsys)
    assert summary["uncorrected"]["held_by_bounds"] == held
    assert summary["uncorrected"]["held_direction_unknown"] == held
    assert (f"; {held} of them only because the axis had not moved since the start, a tool change "
            "or a home move (its direction not known; first at line 4, such as a G43 line's "
            "approach of Z)") in printed
    # the G43 line (line 4) is held either way; BLOCKS.csv says so
    g43 = next(r for r in rows if r["line"] == "4")
    assert g43["corrected"] == "0" and g43["active_bounds"] == "reversal_x"


def test_no_bound_is_counted_where_no_block_was_corrected(tmp_path, capsys):
    """Every block outside the region the model's data reached: nothing corrected, so no bound
    held anything (the backlash's reversal rule was counted at 3 blocks)."""
    support = {"X": (-20.0, 0.0), "Y": (-20.0, 0.0), "Z": (-20.0, 0.0)}
    prog = ("G21 G90 G54\nG0 X100 Y50 Z10\nG1 Z5 F500\nG1 X150\nG1 Y80\nG1 X120 Y60\n"
            "G0 Z20\nM30\n")
    _text, rows, printed, summary = _compensate(tmp_path, _model(tmp_path, support), prog, capsys)
    assert rows and all(r["outside_support"] == "XYZ" and r["corrected"] == "0" for r in rows)
    assert all(r["active_bounds"] == "" for r in rows)
    assert summary["bounded_blocks"] == 0 and summary["active_bounds"] == {}
    assert summary["uncorrected"]["held_by_bounds"] == 0
    assert "\n0 blocks hit a bound\n" in printed


def test_the_bounds_counted_are_those_of_corrected_blocks(tmp_path, capsys):
    """Half the program inside the region, half outside: the summary counts the blocks whose row
    names a bound, and every such row is one the planner corrected (or held by that bound)."""
    support = {"X": (0.0, 120.0)}
    prog = ("G21 G90 G54\nG0 X100 Y50 Z10\nG1 Z5 F500\nG1 X110\nG1 Y80\nG1 X100\nG1 Y60\n"
            "G1 X150\nG1 Y50\nG1 X140\nG0 Z20\nM30\n")
    _text, rows, _printed, summary = _compensate(tmp_path, _model(tmp_path, support), prog, capsys)
    named = [r for r in rows if r["active_bounds"]]
    assert named, "the program is meant to hit the reversal rule inside the region"
    assert summary["bounded_blocks"] == len(named)
    assert all(r["outside_support"] == "" and not r["unknown_axes"] for r in named)
    assert any(r["outside_support"] for r in rows)


def test_render_tells_a_held_block_from_one_outside_the_region(tmp_path):
    """render reads BLOCKS.csv's reasons: a block a bound held (``corrected`` 0 with the bound in
    ``active_bounds``) is not 'outside the region the model's data reached'."""
    from mtcomp.viz.surface import STATUS_REASONS, report_status
    rows = [("Z", "", "0", "", "0"), ("", "", "0", "", "1"), ("", "X", "0", "", "0"),
            ("", "", "0", "reversal_x", "0"), ("", "", "1", "step_x", "0")]
    text = "line,inserted,unknown_axes,outside_support,corrected,active_bounds,uncertain\n"
    text += "".join(f"{i + 3},0,{u},{o},{c},{b},{s}\n" for i, (u, o, c, b, s) in enumerate(rows))
    (tmp_path / "B.csv").write_text(text)
    assert report_status(tmp_path / "B.csv", 5).tolist() == [1, 3, 2, 4, 0]
    assert STATUS_REASONS[4] == "a bound held an axis's whole correction"


# X's correction follows Y (a squareness of X and Y); X is not known before line 4
SQUARENESS = ("G21 G90 G54\nG0 Y10 Z5\nG1 Z0 F300\nG0 X50\nG1 Y60\nG1 Y110 Z-1\nG1 X80\n"
              "G1 Y10\nM30\n")


@pytest.mark.parametrize("writer", ["compiled", "python"])
def test_the_summary_counts_the_lines_given_axis_words_they_did_not_name(tmp_path, capsys,
                                                                         monkeypatch, writer):
    if writer == "python":
        monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
    fm = random_model("xfyz", (), 3, 0.0, None)
    fm.params.set_file_value("C0Y", 50.0)
    model = tmp_path / "square.json"
    save_model(model, fm)
    text, _rows, printed, summary = _compensate(tmp_path, model, SQUARENESS, capsys)
    src, out = SQUARENESS.splitlines(), text.splitlines()
    assert len(out) == len(src)
    added = [k + 1 for k, (a, b) in enumerate(zip(src, out)) if set(_axis_words(b)) - set(_axis_words(a))]
    # X is never written before the program positions it (lines 2 and 3)
    assert "X" not in _axis_words(out[1]) and "X" not in _axis_words(out[2])
    assert len(added) >= 2 and added[0] >= 5, (added, out)
    assert summary["added_axis_words"] == {"lines": len(added), "line": added[0]}
    assert (f"{len(added)} lines written with axis words they did not name (first at line "
            f"{added[0]}): the correction of that axis changes there") in printed
    assert printed.count("written with axis words") == 1



#: programs in a controller's own form whose lines moving only Y get an X word (a squareness of X
#: and Y): Heidenhain's (its line 0 BEGIN PGM being the file's line 1) and Sinumerik's (its file
#: header and DEF line come before the first move: the lines of its G-code equivalent are not the
#: file's). (file name, program, axis words, the lines given X)
OWN_FORMS = {
    "heidenhain": ("p.h", "0 BEGIN PGM T MM\n1 TOOL CALL 1 Z S1000\n2 L X+0 Y+10 Z+5 FMAX\n"
                   "3 L Z+0 F300\n4 L X+50\n5 L Y+60\n6 L Y+110 Z-1\n7 L X+80\n8 END PGM T MM\n",
                   r"\b([XYZ])[+-]", [6, 7]),
    "sinumerik": ("p.mpf", "%_N_SQ_MPF\n;$PATH=/_N_MPF_DIR\nDEF REAL _Z=0\nN10 G90 G54 G17\n"
                  "N20 T1 D1\nN30 M6\nN40 G0 X0 Y10 Z5\nN50 G1 Z=_Z F300\nN60 X50\nN70 Y60\n"
                  "N80 Y110 Z-1\nN90 X80\nN100 M30\n", r"\b([XYZ])-?\d", [10, 11]),
}


@pytest.mark.parametrize("form", sorted(OWN_FORMS))
def test_a_program_in_its_own_form_counts_them_too(tmp_path, capsys, form):
    """The Heidenhain and Sinumerik writers add X to the lines that move only Y, and say so as the
    G-code writer does, naming the lines of the user's file."""
    name, prog, words, want = OWN_FORMS[form]
    fm = random_model("xfyz", (), 3, 0.0, None)
    fm.params.set_file_value("C0Y", 50.0)
    model = tmp_path / "square.json"
    save_model(model, fm)
    text, _rows, printed, summary = _compensate(tmp_path, model, prog, capsys, name=name)
    src, out = prog.splitlines(), text.splitlines()
    assert len(out) == len(src)
    words = re.compile(words)
    added = [k + 1 for k, (a, b) in enumerate(zip(src, out))
             if set(words.findall(b)) - set(words.findall(a))]
    assert added == want, out
    assert summary["added_axis_words"] == {"lines": 2, "line": want[0]}
    assert (f"2 lines written with axis words they did not name (first at line {want[0]})"
            in printed)


@pytest.mark.parametrize("writer", ["compiled", "python"])
def test_a_restart_at_the_number_of_a_split_block_runs_all_of_it(tmp_path, monkeypatch, writer):
    """Block N3 split by two internal nodes: its N word (and G1, F) stay on the first piece, so the
    lines from N3 to N4, which a restart at N3 runs, pass every node and end at N3's corrected end
    (the lines are replayed here, absolute, carrying the axes they do not name)."""
    from mtcomp import load_machine
    from mtcomp.toolpaths import iter_segment_chunks, write_corrected
    if writer == "python":
        monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
    machine = load_machine("xfyz")
    src = "N1 G90 G0 X0 Y0 Z0\nN2 G1 X10 F100\nN3 G1 X40 Y6 F200\nN4 G1 Y20\nN5 M30\n"
    (tmp_path / "p.nc").write_text(src)
    nodes = np.array([[20.0, 2.0, 0.0], [30.0, 4.0, 0.0]]) + [1e-3, -2e-3, 0.0]

    def corrections():
        for c in iter_segment_chunks(tmp_path / "p.nc", machine):
            pts, counts = [], []
            for r in range(len(c)):
                if c.line[r] == 3:
                    pts += list(nodes)
                pts.append(c.end[r] + [1e-3, 1e-3, 0.0])
                counts.append(3 if c.line[r] == 3 else 1)
            yield c, np.array(pts), np.array(counts)
    write_corrected(tmp_path / "p.nc", tmp_path / "o.nc", machine, corrections())
    out = (tmp_path / "o.nc").read_text().splitlines()
    k3 = [i for i, ln in enumerate(out) if ln.startswith("N3 ")]
    k4 = [i for i, ln in enumerate(out) if ln.startswith("N4 ")]
    assert len(k3) == len(k4) == 1
    run = out[k3[0]:k4[0]]
    assert run[0].startswith("N3 G1 ") and "F200" in run[0] and len(run) == 3
    assert not any(re.match(r"\s*N", ln) for ln in run[1:])
    pos = {"X": 10.001, "Y": 0.001, "Z": 0.0}           # where N2 left the output
    reached = []
    for ln in run:
        pos.update({a: float(v) for a, v in _axis_words(ln).items()})
        reached.append([pos["X"], pos["Y"], pos["Z"]])
    want = np.vstack([nodes, [40.001, 6.001, 0.0]])
    np.testing.assert_allclose(reached, want, rtol=0, atol=1e-9)


def test_an_axis_that_gets_no_correction_by_design_does_not_make_a_block_uncorrected():
    """A rotary axis the model's data held at one angle has a correction bound of zero: the plan
    names the bound where the tool axis asks for a turn (cc_max ...), but the block, its X Y Z
    corrected, is corrected; only the travel and the link bounds hold a block's correction."""
    from mtcomp.planner import CompensationProblem, PlannerOptions, output_grid, plan_arrays
    fm = random_model("cafxyz", (), 5, 20.0, None)
    fm.held = {"A": 0.0, "C": 0.0}
    problem = CompensationProblem.from_machine(fm, grid=output_grid(fm.machine))
    rng = np.random.default_rng(2)
    q = np.zeros((40, fm.machine.n_axes))
    for a in "XYZ":
        q[:, fm.machine.index(a)] = rng.uniform(-100.0, 100.0, 40)
    res = plan_arrays(problem, q, options=PlannerOptions(threads=1))
    rotary = [fm.machine.index(a) for a in "AC"]
    assert res.flags[:, rotary].any()                    # the zero bound acted on the turns
    np.testing.assert_array_equal(res.correction[:, rotary], 0.0)
    assert not res.held.any() and res.corrected_blocks().all()
    assert np.abs(res.correction[:, :3]).max() > 1e-3    # X Y Z corrected (mm)
