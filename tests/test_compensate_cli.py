"""`mtcomp compensate` end to end: the written G-code parsed back, the report, the bounds in the
output, bounded programs reported (not failed), 5-axis orientation, bad input. Oracles: the nominal
round trip of the same program, an independent evaluation of the model at the written positions."""
import csv
import json
import math

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.cli import main
from mtcomp.kinematics import forward
from mtcomp.models import ErrorModel, FittedModel, deviation, save_model
from mtcomp.toolpaths import read_program, write_corrected

UNIT_SCALE = {"um": 10e-3, "urad": 20e-6, "mm": 50.0, "1": 0.05}

XFYZ_PROGRAM = """%
O0100 (compensate test)
N10 G21 G90 G17
N20 G0 X-50. Y-40. Z20. ; approach
N30 G1 Z-5. F800 M8
N40 X60. Y-40.
N50 G2 X60. Y40. I0 J40. F600
N60 G1 X-50. Y40.
G1 X-50. Y-38. Z-4.5
N70 G0 Z30.
N80 X120. Y100.
N90 G1 Z0 F300
X140. Y120. Z-2.
M30
%
"""

CAFXYZ_PROGRAM = """%
G21 G90
G0 X0 Y0 Z50 A0 C0
G1 X20 Y-10 Z30 A20 C10 F1000
X40 Y-20 Z20 A35 C45
X30 Y10 Z25 A40 C90
X10 Y30 Z15 A30 C150
G0 Z60
M30
%
"""


def _model(tmp_path, name, seed=3, scale=1.0):
    # polynomial basis: random values per parameter give errors of machine size (a spline has many
    # more parameters, whose random values would add up far beyond the correction bounds)
    machine = load_machine(name).with_basis("polynomial")
    model = ErrorModel(machine)
    fitted = FittedModel.zero(model)
    rng = np.random.default_rng(seed)
    fitted.params.values[:] = scale * rng.normal(size=model.n_params) * np.array(
        [UNIT_SCALE[s.unit] for s in model.param_specs])
    path = tmp_path / f"{name}.json"
    save_model(path, fitted)
    return machine, fitted, path


def _read_report(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return rows


def _run(args, capsys):
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def _written_points(path, machine):
    return read_program(path, machine).segments().end


def _planned_points_as_written(out, prog, machine, rows, chord_tol_mm=1e-3):
    """The planned positions of the report rows (x y z, mm), checked against the written program:
    a row of a straight move is written exactly there; a row of an arc lies within the chord
    tolerance of the written arcs (an arc stays a G2/G3 where the corrected path lies that close to
    one, so its corrected chord ends are not written one by one). Distances to the written arcs
    are taken to their chords at a sagitta of 1e-6 mm."""
    pos = np.array([[float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in rows])
    arc_lines = {b.line for b in read_program(prog, machine).blocks if b.from_arc}
    on_arc = np.array([int(r["line"]) in arc_lines for r in rows])
    dense = read_program(out, machine, chord_tol_mm=1e-6).segments()
    np.testing.assert_allclose(pos[~on_arc], dense.end[~dense.from_arc], rtol=0, atol=1e-9)
    a, b = dense.start[dense.from_arc], dense.end[dense.from_arc]
    q = pos[on_arc]
    ab = b - a
    t = np.clip(np.einsum("qsk,sk->qs", q[:, None, :] - a[None], ab) / np.sum(ab * ab, axis=1), 0, 1)
    gap = np.linalg.norm(q[:, None, :] - (a[None] + t[..., None] * ab[None]), axis=2).min(axis=1)
    assert on_arc.sum() > 10 and gap.max() <= chord_tol_mm + 1e-4
    return pos


def _nominal_points(prog, machine):
    """The program's segment ends on the 4-decimal output grid (mm; the test programs have no
    rotary arcs): the nominal positions the planner corrects (the writer keeps unchanged arcs as
    arcs, so the nominal program written back would hold the unrounded chord ends)."""
    return np.round(read_program(prog, machine).segments().end, 4)


def _actual_minus_nominal(fitted, q_written, q_nominal, chunk, datum=None):
    """Independent: nominal kinematics + model deviation at the written positions, with the context
    of each block (feed and approach directions of the nominal program), less the tip deviation at
    the part's datum (``datum``: machine axis positions of the program's origin, default the
    machine zero; at the model's reference conditions: every approach direction unknown, feed 0):
    what compensate corrects is referenced to it."""
    m = fitted.machine
    cols = {"feed": chunk.feed}
    c0 = fitted.context(len(chunk))
    cols.update({f"dir_{a}": chunk.dirs[:, j].astype(float) for j, a in enumerate(m.axis_names)})
    c = fitted.context(len(chunk), cols)
    tip, axis = forward(m, q_written)
    dev = deviation(fitted.model, q_written, fitted.params.values, c)
    tip0, axis0 = forward(m, q_nominal)
    q_datum = np.zeros_like(q_written) if datum is None else np.broadcast_to(datum, q_written.shape)
    ref = deviation(fitted.model, q_datum, fitted.params.values, c0)[:, :3]
    return np.concatenate([tip - tip0 + dev[:, :3] - ref, axis - axis0 + dev[:, 3:]], axis=1)


@pytest.mark.parametrize("method", ["qp", "newton", "pinv"])
def test_xfyz_program_corrected_and_reported(tmp_path, capsys, method):
    machine, fitted, model_path = _model(tmp_path, "xfyz")
    prog = tmp_path / "in.nc"
    prog.write_text(XFYZ_PROGRAM)
    out, rep, nominal = tmp_path / "out.nc", tmp_path / "blocks.csv", tmp_path / "nominal.nc"
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o", str(out),
                              "--method", method, "--report", str(rep), "--subdivide-tol-um", "0"],
                             capsys)
    assert code == 0, err
    assert "0 blocks hit a bound" in stdout
    write_corrected(prog, nominal, machine, None)
    assert nominal.read_text() == prog.read_text()      # nothing to change: written as it was
    rows = _read_report(rep)
    q_out = _planned_points_as_written(out, prog, machine, rows)
    q_nom = _nominal_points(prog, machine)
    assert q_out.shape == q_nom.shape and q_out.shape[0] > 50     # arc chords included
    # every non-motion line byte for byte, in place
    def still(text):
        return [ln for ln in text.splitlines() if not any(w in ln for w in "XYZ")]
    assert still(out.read_text()) == still(prog.read_text())
    assert len(still(XFYZ_PROGRAM)) == 5
    corr = np.array([[float(r[k]) for k in ("cx_um", "cy_um", "cz_um")] for r in rows])
    np.testing.assert_allclose(corr, (q_out - q_nom) * 1e3, rtol=0, atol=1e-6)
    chunk = read_program(prog, machine).segments()
    e = _actual_minus_nominal(fitted, q_out, q_nom, chunk)
    after = np.array([[float(r[k]) for k in ("ex_after_um", "ey_after_um", "ez_after_um")]
                      for r in rows])
    before = np.array([[float(r[k]) for k in ("ex_before_um", "ey_before_um", "ez_before_um")]
                       for r in rows])
    # the report's prediction is the model at the written positions
    np.testing.assert_allclose(after, e[:, :3] * 1e3, rtol=0, atol=2e-4)
    e0 = _actual_minus_nominal(fitted, q_nom, q_nom, chunk)
    np.testing.assert_allclose(before, e0[:, :3] * 1e3, rtol=0, atol=2e-4)
    assert np.abs(before).max() > 3.0   # um: errors far above the 0.06 um left after compensation
    # what remains is the 4-decimal rounding of the output (0.05 um per axis)
    assert np.abs(e[:, :3]).max() * 1e3 < 0.06
    assert all(r["active_bounds"] == "" for r in rows)


def test_bounds_hold_in_the_output_and_are_reported(tmp_path, capsys):
    machine, fitted, model_path = _model(tmp_path, "xfyz", seed=4, scale=2.0)
    prog = tmp_path / "in.nc"
    prog.write_text(XFYZ_PROGRAM)
    out, rep, nominal = tmp_path / "out.nc", tmp_path / "blocks.csv", tmp_path / "nominal.nc"
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o", str(out),
                              "--max-correction-um", "4", "--max-step-um", "0.3",
                              "--report", str(rep)], capsys)
    assert code == 0, err
    rows = _read_report(rep)
    hit = [r for r in rows if r["active_bounds"]]
    assert len(hit) > 5
    assert f"{len(hit)} blocks hit a bound" in stdout
    assert "worst remaining predicted deviation" in stdout
    kinds = {k for r in hit for k in r["active_bounds"].split(";")}
    assert kinds & {"cx_max", "cx_min", "cy_max", "cy_min", "cz_max", "cz_min"}
    assert kinds & {"step_x", "step_y", "step_z"}
    worst = max(float(r["e_after_um"]) for r in rows)
    assert f"{worst:.3f} um" in stdout
    assert worst > 1.0
    write_corrected(prog, nominal, machine, None)
    chunk = read_program(prog, machine).segments()
    # internal nodes may have been added: map output rows to the report, whose nominal is x - c
    pos = _planned_points_as_written(out, prog, machine, rows)
    corr_um = np.array([[float(r[k]) for k in ("cx_um", "cy_um", "cz_um")] for r in rows])
    ends = np.array([r["inserted"] == "0" for r in rows])
    np.testing.assert_allclose(pos[ends] - corr_um[ends] * 1e-3, _nominal_points(prog, machine),
                               rtol=0, atol=1e-9)
    assert np.all(np.abs(corr_um) <= 4.0 + 1e-6)
    rapid = np.array([r["rapid"] == "1" for r in rows])
    steps = np.abs(np.diff(corr_um, axis=0))
    assert np.all(steps[~rapid[1:]] <= 0.3 + 1e-6)
    assert len(chunk) == int(ends.sum())


def test_five_axis_corrects_orientation_too(tmp_path, capsys):
    machine, fitted, model_path = _model(tmp_path, "cafxyz", seed=5)
    prog = tmp_path / "in.nc"
    prog.write_text(CAFXYZ_PROGRAM)
    out, rep, nominal = tmp_path / "out.nc", tmp_path / "blocks.csv", tmp_path / "nominal.nc"
    code, stdout, err = _run(["compensate", "cafxyz", str(model_path), str(prog), "-o", str(out),
                              "--report", str(rep), "--max-correction-urad", "2000",
                              "--max-correction-um", "200", "--max-step-um", "200"], capsys)
    assert code == 0, err
    rows = _read_report(rep)
    assert {"ca_urad", "cc_urad", "ei_after_urad", "e_axis_before_urad"} <= set(rows[0])
    write_corrected(prog, nominal, machine, None)
    ends = np.array([r["inserted"] == "0" for r in rows])
    assert (~ends).sum() > 0          # big rotary moves: the corrected path needs internal nodes
    q_all = _written_points(out, machine)
    q_out = q_all[ends]
    q_nom = _written_points(nominal, machine)
    chunk = read_program(prog, machine).segments()
    e = _actual_minus_nominal(fitted, q_out, q_nom, chunk)
    e0 = _actual_minus_nominal(fitted, q_nom, q_nom, chunk)
    feed = ~chunk.rapid
    # the first rapid goes to A = 0, where C cannot tilt the tool: look at the tilted blocks
    tilted = feed & (np.abs(q_nom[:, 3]) > math.radians(10))
    assert np.linalg.norm(e0[tilted, 3:], axis=1).min() * 1e6 > 5.0
    # the written angles have a 1e-4 deg = 1.7 urad resolution: that is what is left
    assert np.linalg.norm(e[tilted, 3:], axis=1).max() * 1e6 < 2.0
    assert np.linalg.norm(e[tilted, :3], axis=1).max() * 1e3 < 0.6
    ca = np.array([float(r["ca_urad"]) for r in rows])[ends]
    np.testing.assert_allclose(ca, np.degrees(q_out[:, 3] - q_nom[:, 3]) / 180 * math.pi * 1e6,
                               rtol=0, atol=1e-5)
    # --orientation-weight: a tool axis weighed at 1e-4 um per urad is left (nearly) as it was,
    # while the tip is still corrected
    code, stdout, err = _run(["compensate", "cafxyz", str(model_path), str(prog), "-o", str(out),
                              "--report", str(rep), "--max-correction-urad", "2000",
                              "--max-correction-um", "200", "--max-step-um", "200",
                              "--orientation-weight", "1e-4"], capsys)
    assert code == 0, err
    ends = np.array([r["inserted"] == "0" for r in _read_report(rep)])
    e = _actual_minus_nominal(fitted, _written_points(out, machine)[ends], q_nom, chunk)
    left = np.linalg.norm(e[tilted, 3:], axis=1) / np.linalg.norm(e0[tilted, 3:], axis=1)
    assert left.min() > 0.9
    assert np.linalg.norm(e[tilted, :3], axis=1).max() * 1e3 < 0.6


@pytest.mark.parametrize("text", ["G21 G90\r\n(no motion)\r\nM3 S6000\r\nG4 P60\r\nM5\r\nM30\r\n",
                                  "G21\nG28\nM30\n"])
def test_a_program_with_nothing_to_correct_is_written_unchanged(tmp_path, capsys, text):
    """A warm-up macro moves nothing, a program of home moves only from where the machine stands:
    no block to correct. Written byte for byte (exit 0), said in a note, BLOCKS.csv its header
    alone and the summary's blocks 0; render has nothing to draw and says so."""
    _machine, _fitted, model_path = _model(tmp_path, "xfyz")
    prog, out = tmp_path / "warm.nc", tmp_path / "out.nc"
    prog.write_bytes(text.encode())
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o", str(out),
                              "--report", str(tmp_path / "r.csv"), "--json",
                              str(tmp_path / "s.json")], capsys)
    assert code == 0, err
    assert out.read_bytes() == text.encode()
    assert "it is written unchanged, byte for byte" in stdout
    assert len((tmp_path / "r.csv").read_text().splitlines()) == 1
    assert json.loads((tmp_path / "s.json").read_text())["blocks"] == 0
    code, _stdout, err = _run(["render", "xfyz", str(model_path), str(prog), "-o",
                               str(tmp_path / "m.png"), "--backend", "matplotlib"], capsys)
    assert code == 2 and "no motion block in the program: nothing to draw" in err


def test_bad_input_exits_2_and_writes_nothing(tmp_path, capsys):
    machine, fitted, model_path = _model(tmp_path, "xfyz")
    prog = tmp_path / "in.nc"
    prog.write_text(XFYZ_PROGRAM)
    out = tmp_path / "out.nc"
    far = tmp_path / "far.nc"
    far.write_text("G21 G90\nG0 X0 Y0 Z0\nG1 X500 F100\nM30\n")
    garbled = tmp_path / "bad.nc"
    garbled.write_text("G21 G90\nG1 X1 Y$ F100\n")
    cases = [
        (["compensate", "xfyz", str(model_path), str(tmp_path / "none.nc"), "-o", str(out)], "none.nc"),
        (["compensate", "xfyz", str(model_path), str(far), "-o", str(out)], "far.nc:3"),
        (["compensate", "xfyz", str(model_path), str(garbled), "-o", str(out)], "bad.nc:2"),
        (["compensate", "xfyz", str(model_path), str(prog), "-o", str(out), "--max-step-um", "-1"],
         "--max-step-um"),
        (["compensate", "xfyz", str(model_path), str(prog), "-o", str(prog)], "overwrite"),
        (["compensate", "xfyz", str(model_path), str(prog), "-o", str(out), "--orientation-weight",
          "0"], "--orientation-weight"),
        (["compensate", "cafxyz", str(model_path), str(prog), "-o", str(out)], "XFYZ"),
    ]
    for args, expect in cases:
        code, stdout, err = _run(args + ["--report", str(tmp_path / "r.csv")], capsys)
        assert code == 2, (args, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and expect in lines[0], err
        assert "Traceback" not in err
        assert not out.exists() and not (tmp_path / "r.csv").exists()
    assert prog.read_text() == XFYZ_PROGRAM
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]


def test_inch_program_keeps_bounds_on_the_inch_grid(tmp_path, capsys):
    machine, fitted, model_path = _model(tmp_path, "xfyz", seed=6, scale=2.0)
    prog = tmp_path / "in.nc"
    prog.write_text("G20 G90\nG0 X-2 Y-1.5 Z0.5\nG1 Z-0.2 F40\nX2 Y-1.5\nX2 Y1.5\nX-2 Y1.5\nM30\n")
    out, nominal = tmp_path / "out.nc", tmp_path / "nominal.nc"
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o", str(out),
                              "--max-correction-um", "3", "--max-step-um", "1",
                              "--subdivide-tol-um", "0"], capsys)
    assert code == 0, err
    write_corrected(prog, nominal, machine, None)
    corr_inch = (_written_points(out, machine) - _written_points(nominal, machine)) / 25.4
    k = corr_inch / 1e-5                                   # whole steps of the 5th inch decimal
    np.testing.assert_allclose(k, np.round(k), rtol=0, atol=1e-6)
    corr_um = corr_inch * 25.4e3
    assert np.all(np.abs(corr_um) <= 3.0 + 1e-6)
    assert np.all(np.abs(np.diff(corr_um[1:], axis=0)) <= 1.0 + 1e-6)   # block 1 follows a rapid
    assert np.abs(corr_um).max() > 0.5


def _model_with_support(tmp_path, support):
    machine, fitted, path = _model(tmp_path, "xfyz", seed=7)
    fitted.support = support
    save_model(path, fitted)
    return machine, fitted, path


def test_blocks_outside_the_support_are_not_corrected_unless_asked(tmp_path, capsys):
    machine, fitted, model_path = _model_with_support(tmp_path, {"X": (-20.0, 20.0),
                                                                 "Y": (-20.0, 20.0)})
    prog = tmp_path / "in.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F300\nX15\nX60\nY10\nX0\nM30\n")
    out, rep = tmp_path / "out.nc", tmp_path / "b.csv"
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o", str(out),
                              "--report", str(rep), "--subdivide-tol-um", "0"], capsys)
    assert code == 0, err
    rows = _read_report(rep)
    outside = [r for r in rows if r["outside_support"]]
    assert [int(r["line"]) for r in outside] == [5, 6]           # X60: lines 5 and 6
    assert all(r["outside_support"] == "X" and r["corrected"] == "0" for r in outside)
    for r in outside:
        assert float(r["cx_um"]) == 0 and float(r["cy_um"]) == 0 and float(r["cz_um"]) == 0
    inside = [r for r in rows if not r["outside_support"]]
    # the others are corrected (near the part's datum, the origin, by little: 0.1 um)
    norm = lambda r: float(np.hypot(np.hypot(float(r["cx_um"]), float(r["cy_um"])), float(r["cz_um"])))  # noqa: E731
    assert all(r["corrected"] == "1" for r in inside) and max(norm(r) for r in inside) >= 0.1
    assert "2 blocks outside the region the model's data reached (X 2; first at line 5): not " \
           "corrected (pass --extrapolate" in stdout
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o", str(out),
                              "--report", str(rep), "--subdivide-tol-um", "0", "--extrapolate"],
                             capsys)
    assert code == 0, err
    rows = _read_report(rep)
    assert all(r["corrected"] == "1" for r in rows)
    assert max(norm(r) for r in rows if r["line"] == "5") > 0.3
    assert "corrected anyway (--extrapolate)" in stdout


def test_nodes_inserted_outside_the_support_are_not_corrected(tmp_path, capsys):
    """A move from outside the region the data reached into it: the nodes the planner inserts on
    its way are blocks like any other, so those outside the region keep zero correction (a new
    user's trial found +15 um written at x = -86 mm with data from -20 to 20 mm)."""
    machine, fitted, model_path = _model_with_support(tmp_path, {"X": (-20.0, 20.0),
                                                                 "Y": (-20.0, 20.0)})
    prog = tmp_path / "in.nc"
    prog.write_text("G21 G90\nG0 X-100 Y0 Z0\nG1 X10 F100\nM30\n")
    out, rep = tmp_path / "out.nc", tmp_path / "b.csv"
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o", str(out),
                              "--report", str(rep), "--subdivide-tol-um", "0.01"], capsys)
    assert code == 0, err
    rows = _read_report(rep)
    nodes = [r for r in rows if r["inserted"] == "1"]
    assert nodes, "the move was not subdivided: the test does not test"
    for r in rows:
        if float(r["x_mm"]) < -20.0 - 1e-6:
            assert r["corrected"] == "0" and r["outside_support"] == "X", r
            assert float(r["cx_um"]) == 0 and float(r["cy_um"]) == 0 and float(r["cz_um"]) == 0


def test_a_program_no_block_of_which_is_known_gets_no_figures_and_the_fix(tmp_path, capsys):
    """A 3-axis program on a 5-axis machine: A and C are never named, so no block is evaluated;
    the summary says so (not 'max 0.000 um', which reads as a perfect machine) and names
    --start-position; with it the blocks are evaluated and corrected."""
    _, _, model_path = _model(tmp_path, "cafxyz")
    prog = tmp_path / "in.nc"
    prog.write_text("G21 G90\nG0 X10 Y10 Z5\nG1 Z0 F300\nX30\nM30\n")
    out = tmp_path / "out.nc"
    code, stdout, err = _run(["compensate", "cafxyz", str(model_path), str(prog), "-o", str(out)],
                             capsys)
    assert code == 0, err
    assert "predicted tool-tip deviation: not evaluated" in stdout and "max 0.000" not in stdout
    assert "--start-position, e.g. A=0,C=0" in stdout
    code, stdout, err = _run(["compensate", "cafxyz", str(model_path), str(prog), "-o", str(out),
                              "--start-position", "A=0,C=0"], capsys)
    assert code == 0, err
    assert "predicted tool-tip deviation before: max" in stdout and "not evaluated" not in stdout


def test_an_expanded_program_reports_the_lines_of_its_source(tmp_path, capsys):
    """A subroutine called twice: BLOCKS.csv names the subroutine's lines (twice) and the calls'
    own lines, the lines of the user's file, not of the expansion; render pairs that report."""
    _, _, model_path = _model(tmp_path, "xfyz")
    prog = tmp_path / "in.ngc"
    prog.write_text("G21 G90\n"                 # 1
                    "o100 sub\n"                # 2
                    "  G1 X#1 F100\n"           # 3
                    "  G1 Y#1\n"                # 4
                    "o100 endsub\n"             # 5
                    "G0 X0 Y0 Z0\n"             # 6
                    "o100 call [5]\n"           # 7
                    "o100 call [9]\n"           # 8
                    "M30\n")
    out, rep = tmp_path / "out.nc", tmp_path / "b.csv"
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o", str(out),
                              "--report", str(rep), "--subdivide-tol-um", "0"], capsys)
    assert code == 0, err
    assert [int(r["line"]) for r in _read_report(rep)] == [6, 3, 4, 3, 4]
    code, _, err = _run(["render", "xfyz", str(model_path), str(prog), "--report", str(rep), "-o",
                         str(tmp_path / "m.png"), "--backend", "matplotlib", "--size", "300x150"],
                        capsys)
    assert code == 0, err


def test_cutter_radius_compensation_is_said(tmp_path, capsys):
    _, _, model_path = _model(tmp_path, "xfyz")
    for text, said in (("G21 G90\nG0 X0 Y0 Z5\nG42 D1 G1 X10 F100\nG40 X20\nM30\n", True),
                       ("G21 G90\nG0 X0 Y0 Z5\nG1 X10 F100\nX20\nM30\n", False)):
        prog = tmp_path / "in.nc"
        prog.write_text(text)
        code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o",
                                  str(tmp_path / "out.nc")], capsys)
        assert code == 0, err
        assert ("cutter radius compensation (G41/G42)" in stdout) == said


def test_the_program_given_for_the_model_is_named_as_such(tmp_path, capsys):
    _, _, model_path = _model(tmp_path, "xfyz")
    prog = tmp_path / "in.nc"
    prog.write_text("%\nO1000\nG21 G90\nG0 X0 Y0\nM30\n%\n")
    code, _, err = _run(["compensate", "xfyz", str(prog), str(model_path), "-o",
                         str(tmp_path / "o.nc")], capsys)
    assert code == 2 and "looks like a G-code program" in err and err.count("\n") == 1
    broken = tmp_path / "broken.json"
    broken.write_text('{"format": ')
    code, _, err = _run(["compensate", "xfyz", str(broken), str(prog), "-o",
                         str(tmp_path / "o.nc")], capsys)
    assert code == 2 and "not valid JSON" in err and "G-code" not in err


def test_figures_over_the_corrected_blocks_only(tmp_path, capsys):
    import json
    machine, fitted, model_path = _model_with_support(tmp_path, {"X": (-20.0, 20.0),
                                                                 "Y": (-20.0, 20.0)})
    prog = tmp_path / "in.nc"
    # line 2 leaves Z unknown (not corrected), lines 5-6 lie outside the support (not corrected)
    prog.write_text("G21 G90\nG0 X0 Y0\nG0 Z5\nG1 Z0 F300\nX60\nY10\nX15\nX0\nM30\n")
    out, rep, js = tmp_path / "out.nc", tmp_path / "b.csv", tmp_path / "s.json"
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o", str(out),
                              "--report", str(rep), "--json", str(js), "--subdivide-tol-um", "0"],
                             capsys)
    assert code == 0, err
    rows = _read_report(rep)
    done = [r for r in rows if r["corrected"] == "1"]
    assert [int(r["line"]) for r in done] == [3, 4, 7, 8]
    known = [r for r in rows if not r["unknown_axes"]]     # the overall figures leave these out
    # the block with Z unknown: no Z position and no predicted deviation to show (blank, not 0)
    (blind,) = [r for r in rows if r["unknown_axes"]]
    assert blind["unknown_axes"] == "Z" and blind["z_mm"] == blind["cz_um"] == blind["e_before_um"] == ""
    assert blind["x_mm"] == "0.0000" and blind["cx_um"] == "0.0000"
    figures = json.loads(js.read_text())

    def stats(rs, when):
        e = np.array([float(r[f"e_{when}_um"]) for r in rs])
        return e.max(), np.sqrt(np.mean(e ** 2))
    c = figures["corrected"]
    assert c["blocks"] == 4 and figures["evaluated_blocks"] == len(known) == 6
    for when in ("before", "after"):
        np.testing.assert_allclose([c[f"max_{when}_um"], c[f"rms_{when}_um"]], stats(done, when),
                                   rtol=0, atol=1e-4)
        np.testing.assert_allclose([figures[f"max_{when}_um"], figures[f"rms_{when}_um"]],
                                   stats(known, when), rtol=0, atol=1e-4)
    assert figures["uncorrected"] == {"unknown_axes": 1, "outside_support": 2, "uncertain": 0,
                                       "direction_not_read": 0,
                                       "uncertain_contour": 0, "indistinct_from_zero": 0,
                                       "held_by_bounds": 0, "held_direction_unknown": 0}
    # the corrected blocks alone show what the correction did; the outside ones keep their error
    assert c["rms_after_um"] < 0.5 * c["rms_before_um"] < figures["rms_after_um"]
    line = next(t for t in stdout.splitlines() if t.startswith("over the 4 blocks corrected"))
    assert f"rms {c['rms_after_um']:.3f} um" in line and f"rms {c['rms_before_um']:.3f} um" in line
    # the figures hold the 2 blocks outside the region, not the one with an unknown axis
    assert "(these figures include the 2 blocks left uncorrected" in stdout


def test_no_internal_nodes_from_a_start_the_program_has_not_given(tmp_path, capsys):
    # internal nodes lie on the line from the previous block's end; after a home move, a tool
    # change or a drilling cycle the machine does not stand there, so such a move gets none (they
    # would be positions the program never gave: after the cycle, at the hole's depth)
    machine, fitted, model_path = _model(tmp_path, "xfyz")
    prog = tmp_path / "in.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z10\nG1 X300 Y200 F500\nG28 Z0\nG1 X0 Y0 Z-1\n"
                    "T2 M6\nG1 X300 Y200 Z5\nG99 G81 X5 Y5 Z-3 R2 F100\nG80\nG1 X300 Y200\n"
                    "X0 Y0\nM30\n")
    out, rep = tmp_path / "out.nc", tmp_path / "b.csv"
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o", str(out),
                              "--report", str(rep), "--subdivide-tol-um", "0.001"], capsys)
    assert code == 0, err
    inserted = {int(r["line"]) for r in _read_report(rep) if r["inserted"] == "1"}
    assert inserted == {3, 11}          # the moves that start where the program put the machine
    text = out.read_text().splitlines()
    after_cycle = text[text.index("G80") + 1].split()      # one line straight to X300 Y200
    assert after_cycle[0] == "G1" and abs(float(after_cycle[1][1:]) - 300.0) < 0.05


def test_model_without_support_is_said_once(tmp_path, capsys):
    machine, fitted, model_path = _model(tmp_path, "xfyz")
    prog = tmp_path / "in.nc"
    prog.write_text(XFYZ_PROGRAM)
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o",
                              str(tmp_path / "o.nc")], capsys)
    assert code == 0, err
    assert stdout.count("the model does not state the region its data reached") == 1
    assert stdout.count("assumed: work offset G54 = 0") == 1


def test_work_offset_and_tool_length_reach_the_model(tmp_path, capsys):
    machine, fitted, model_path = _model(tmp_path, "xfyz", seed=8)
    prog = tmp_path / "in.nc"
    prog.write_text("G21 G90 G54\nT1 M6\nG0 G43 H1 Z20.\nG0 X-50. Y-40.\nG1 Z-5. F800\nX60.\nY40.\nM30\n")
    offsets = tmp_path / "offsets.toml"
    offsets.write_text("[work_offsets]\nG54 = {X = 100.0, Y = 50.0, Z = -200.0}\n"
                       "[tool_lengths]\nH1 = 80.0\n")
    rep = tmp_path / "b.csv"
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o",
                              str(tmp_path / "o.nc"), "--offsets", str(offsets), "--report",
                              str(rep), "--subdivide-tol-um", "0"], capsys)
    assert code == 0, err
    assert "assumed" not in stdout
    rows = _read_report(rep)
    # reported and written positions are the program's; the model saw them + the offset, tool 80 mm
    known = np.array([r["unknown_axes"] == "" for r in rows])
    assert known.sum() >= 4
    rows = [r for r, k in zip(rows, known) if k]            # unknown axes have blank cells
    known = known[known]
    q_prog = np.array([[float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in rows])
    corr = np.array([[float(r[k]) for k in ("cx_um", "cy_um", "cz_um")] for r in rows]) * 1e-3
    before = np.array([[float(r[k]) for k in ("ex_before_um", "ey_before_um", "ez_before_um")]
                       for r in rows])
    q_mach = q_prog - corr + [100.0, 50.0, -200.0]
    c = fitted.context(len(rows), {"tool_length": np.full(len(rows), 80.0)})
    dev = deviation(fitted.model, q_mach, fitted.params.values, c)
    # referenced to the part's datum: the program's origin, the work offset, in X Y as the probe
    # found it (the machine's tool length, 100 mm), in Z with the tool of H1 (set on its own)
    at = np.tile([100.0, 50.0, -200.0], (len(rows), 1))
    datum = deviation(fitted.model, at, fitted.params.values, c)
    probe = fitted.context(len(rows), {"tool_length": np.full(len(rows), machine.tool_length)})
    datum[:, :2] = deviation(fitted.model, at, fitted.params.values, probe)[:, :2]
    np.testing.assert_allclose(before[known], (dev - datum)[known, :3] * 1e3, rtol=0, atol=2e-3)
    # an oracle with another offset disagrees: the test can fail
    dev0 = deviation(fitted.model, q_prog - corr, fitted.params.values, c)
    assert np.abs(before[known] - (dev0 - datum)[known, :3] * 1e3).max() > 0.05
    # the flags do the same as the file; a bad flag is one clear line
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o",
                              str(tmp_path / "o2.nc"), "--work-offset", "G54=X100,Q5"], capsys)
    assert code == 2 and "--work-offset G54=X100,Q5" in err and len(err.strip().splitlines()) == 1


def test_drilling_cycles_are_corrected_as_cycles(tmp_path, capsys):
    machine, fitted, model_path = _model(tmp_path, "xfyz")
    prog = tmp_path / "in.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z10\nG99 G82 X5 Y5 Z-3 R2 P0.5 F100\nX10\nY10\nG80\n"
                    "G0 Z10\nX0 Y0\nG28 G91 X0 Y0\nG90\nG98 G81 Z-3 R2\nG80\nM30\n")
    out, rep = tmp_path / "o.nc", tmp_path / "b.csv"
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o", str(out),
                              "--report", str(rep)], capsys)
    assert code == 0, err
    assert "3 drilling cycle lines (G73, G81-G89) kept as cycles, each hole corrected" in stdout
    assert "1 drilling cycle line (G73, G81-G89) passed through unchanged" in stdout
    src, dst = prog.read_text().splitlines(), out.read_text().splitlines()
    rows = np.genfromtxt(rep, delimiter=",", names=True, dtype=None, encoding=None)
    holes = rows[np.isin(rows["line"], [3, 4, 5])]
    assert holes["inserted"].tolist() == [0, 0, 0]          # one block per hole
    nominal = np.array([[5, 5, -3], [10, 5, -3], [10, 10, -3]])
    written = np.column_stack([holes["x_mm"], holes["y_mm"], holes["z_mm"]])
    corr = np.column_stack([holes["cx_um"], holes["cy_um"], holes["cz_um"]]) * 1e-3
    np.testing.assert_allclose(written - corr, nominal, rtol=0, atol=1e-9)
    assert np.abs(corr).max() > 1e-4                        # the model asks for a correction here
    # the cycle line carries the report's positions, R moved by the Z correction
    x, y, z = written[0]
    r = 2 + corr[0, 2]
    # a word whose correction is zero (the hole at the part's datum's Y: relative to it nothing to
    # correct) stays as the program wrote it
    word = lambda v, c, old: old if c == 0 else f"{v:.4f}"  # noqa: E731
    assert dst[2] == (f"G99 G82 X{word(x, corr[0, 0], '5')} Y{word(y, corr[0, 1], '5')} "
                      f"Z{word(z, corr[0, 2], '-3')} R{word(r, corr[0, 2], '2')} P0.5 F100")
    assert dst[10:] == src[10:]                             # the hole at an unknown X Y as written


def test_program_without_units_is_warned(tmp_path, capsys):
    machine, fitted, model_path = _model(tmp_path, "xfyz")
    prog = tmp_path / "in.nc"
    prog.write_text("G90\nG0 X1 Y1 Z1\nG1 X2 F100\n")
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o",
                              str(tmp_path / "o.nc")], capsys)
    assert code == 0, err
    assert "warning: the program has no G20/G21" in stdout
    code, stdout, err = _run(["compensate", "xfyz", str(model_path), str(prog), "-o",
                              str(tmp_path / "o.nc"), "--units", "inch", "--report",
                              str(tmp_path / "b.csv")], capsys)
    assert code == 0, err
    assert "taken as inch (--units)" in stdout
    rows = _read_report(tmp_path / "b.csv")
    assert float(rows[-1]["x_mm"]) == pytest.approx(50.8, rel=0, abs=0.02)   # 2 in, corrected


def test_rotary_axes_a_program_never_names_are_declared_with_start_position(tmp_path, capsys):
    machine, fitted, model_path = _model(tmp_path, "cafxyz", seed=9)
    prog = tmp_path / "in.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z20\nG1 X30 F500\nY30\nM30\n")
    rep = tmp_path / "b.csv"
    out = tmp_path / "o.nc"
    code, stdout, err = _run(["compensate", "cafxyz", str(model_path), str(prog), "-o", str(out),
                              "--report", str(rep), "--max-correction-urad", "2000"], capsys)
    assert code == 0, err
    rows = _read_report(rep)
    # A and C are never named: their positions are not known, nothing is corrected or written
    assert all(r["unknown_axes"] == "AC" and r["corrected"] == "0" for r in rows)
    assert all(r["a_deg"] == r["c_deg"] == r["ei_before_urad"] == "" and r["x_mm"] for r in rows)
    assert out.read_text() == prog.read_text()
    code, stdout, err = _run(["compensate", "cafxyz", str(model_path), str(prog), "-o", str(out),
                              "--report", str(rep), "--max-correction-urad", "2000",
                              "--start-position", "A=0,C=0"], capsys)
    assert code == 0, err
    rows = _read_report(rep)
    assert all(r["unknown_axes"] == "" and r["corrected"] == "1" for r in rows)
    assert max(abs(float(r["cz_um"])) for r in rows) > 0.1
    code, stdout, err = _run(["compensate", "cafxyz", str(model_path), str(prog), "-o",
                              str(tmp_path / "o2.nc"), "--start-position", "B=0"], capsys)
    assert code == 2 and "has no B axis" in err


def test_feed_moves_without_a_feed_are_noted_when_the_model_has_feed_terms(tmp_path, capsys):
    """A model with a feed offset on X takes a move without F at 0 mm/min: the user is told which
    lines; with F in the program, or with no feed term in the model, nothing is said."""
    from mtcomp.models import FeedOffset
    machine = load_machine("xfyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine, [FeedOffset("X")]))
    fitted.params["FOFF_X"] = 5e-3                            # 5 um per m/min
    path = tmp_path / "feed.json"
    save_model(path, fitted)
    _, _, plain = _model(tmp_path, "xfyz")
    no_f = tmp_path / "nof.nc"
    no_f.write_text("G21 G90\nG0 X0 Y0 Z5\nG1 Z0\nG1 X50\nM30\n")
    with_f = tmp_path / "f.nc"
    with_f.write_text("G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F800\nG1 X50\nM30\n")
    for model, prog, noted in ((path, no_f, True), (path, with_f, False), (plain, no_f, False)):
        code, out, err = _run(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o.nc")],
                              capsys)
        assert code == 0, err
        said = ("warning: 2 feed moves from line 3 on have no feed (no F word before them): the model's "
                "feed terms (feed_dependent_offset:X) take them at 0 mm/min") in out
        assert said == noted, out


def test_a_datum_outside_the_data_is_said(tmp_path, capsys):
    """The corrections are referenced to the deviation at the part's datum; a datum outside the
    region the model's data reached gets one line (the model's continuation is its reference)."""
    machine, fitted, model_path = _model_with_support(tmp_path, {"X": (-20.0, 20.0), "Y": (-20.0, 20.0)})
    prog = tmp_path / "in.nc"
    prog.write_text("G21 G90 G54\nG0 X-40 Y0 Z5\nG1 Z0 F300\nX-30\nM30\n")
    args = ["compensate", "xfyz", str(model_path), str(prog), "-o", str(tmp_path / "o.nc")]
    code, stdout, err = _run(args + ["--work-offset", "G54=X30,Y0,Z0"], capsys)
    assert code == 0, err
    assert "the part's datum of G54 (X 30) lies outside the region the model's data reached" in stdout
    code, stdout, err = _run(args + ["--work-offset", "G54=X10,Y0,Z0"], capsys)
    assert code == 0, err
    assert "the part's datum" not in stdout


def test_a_program_with_no_corrected_block_says_so(tmp_path, capsys):
    """Every block outside the region the model's data reached: the figures over the corrected
    blocks are of none, and a warning says that nothing was corrected (it was silent: 'over the 0
    blocks corrected: ... 0.000 um', exit 0)."""
    _, _, path = _model_with_support(tmp_path, {"X": (-1.0, 1.0)})
    prog = tmp_path / "far.nc"
    prog.write_text("G21 G90\nG0 X100 Y0 Z0\nG1 X150 F500\nM30\n")
    assert main(["compensate", "xfyz", str(path), str(prog), "-o", str(tmp_path / "o.nc")]) == 0
    out = capsys.readouterr().out
    assert "warning: no block was corrected (for the reasons above): the output carries no " \
           "correction" in out
    assert (tmp_path / "o.nc").read_text() == prog.read_text()


def test_a_work_offset_without_z_is_said_and_named_when_nothing_is_corrected(tmp_path, capsys):
    """--work-offset G55=X-80,Y-60 with Z left out: Z of G55 is 0, so the program's Z 5 .. -4 stand
    at machine Z 5 .. -4, above the -300 .. -100 mm the data reached, and no block is corrected; a
    quality engineer's run said only "no block was corrected". Now a note says Z was taken as 0 and
    the warning names the offset. With Z given (-200: machine Z -195 .. -204) the blocks are
    corrected and neither line is printed."""
    machine, fitted, model_path = _model_with_support(
        tmp_path, {"X": (-200.0, 200.0), "Y": (-200.0, 200.0), "Z": (-300.0, -100.0)})
    prog = tmp_path / "in.nc"
    prog.write_text("G21 G90\nG55\nG0 X0 Y0 Z5\nG1 Z-4 F300\nX40\nY30\nG0 Z5\nM30\n")
    out = tmp_path / "out.nc"
    args = ["compensate", "xfyz", str(model_path), str(prog), "-o", str(out), "-q"]
    code, stdout, err = _run(args + ["--work-offset", "G55=X-80,Y-60"], capsys)
    assert code == 0, err
    said = stdout.splitlines()
    assert said.count("assumed: Z of work offset G55 = 0 (given with X, Y only; the program "
                      "positions Z too): give every axis it positions, e.g. --work-offset "
                      "G55=X..,Y..,Z..") == 1, stdout
    warning = [t for t in said if t.startswith("warning: no block was corrected")]
    assert warning == ["warning: no block was corrected (for the reasons above): the output carries "
                       "no correction; Z of work offset G55 taken as 0 (not given): the program "
                       "stands outside the region the model's data reached on Z: give that "
                       "offset's every axis"], stdout
    code, stdout, err = _run(args + ["--work-offset", "G55=X-80,Y-60,Z-200"], capsys)
    assert code == 0, err
    assert "no block was corrected" not in stdout and "of work offset G55 = 0" not in stdout, stdout
