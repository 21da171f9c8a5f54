"""The standard-error gate acts per contour: a contour with one block whose correction's standard
error exceeds --max-correction-sd-um is left uncorrected whole, so no stretch of a cut is left out
of a correction its neighbours carry (a dent). Oracles: the standard error from finite differences
of the model's deviation and its covariance, the contours of the program read by hand, and the
dent measured on BLOCKS.csv."""
import csv
import json

import numpy as np
import pytest

import mtcomp.compensation
from mtcomp import load_machine
from mtcomp.cli import main
from mtcomp.models import ErrorModel, FittedModel, deviation, save_model
from mtcomp.planner import CompensationProblem, PlannerOptions, plan_arrays

SIGMA = 3e-3             # standard error of EXX_1, internal units


def _fitted(exx_um_per_m):
    """X's positioning error exx_um_per_m * x (x in m), its one parameter's standard error SIGMA."""
    machine = load_machine("xfyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine))
    fitted.params.set_file_value("EXX_1", exx_um_per_m)
    fitted.support = {"X": (-400.0, 400.0)}
    fitted.uncertainty = {"names": ["EXX_1"], "covariance": np.array([[SIGMA ** 2]]),
                          "undetermined": np.zeros((1, 0))}
    return machine, fitted


def _sd_oracle(fitted, q):
    """(n,) um: SIGMA times the largest tip component's sensitivity to EXX_1, central differences."""
    p = np.asarray(fitted.params.values, dtype=float)
    dp = np.zeros_like(p)
    dp[fitted.params.index("EXX_1")] = 1e-6
    d = (deviation(fitted.model, q, p + dp)[:, :3] - deviation(fitted.model, q, p - dp)[:, :3]) / 2e-6
    return 1e3 * SIGMA * np.max(np.abs(d), axis=1)


# contour A: feed moves out to x = 250 mm; a rapid; contour B: feed moves at x in [-120, -60] mm
XA = [50.0, 100.0, 150.0, 200.0, 250.0]
XB = [-60.0, -80.0, -100.0, -120.0]


def _two_contours():
    x = np.array(XA + [-50.0] + XB)
    q = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    rapid = np.zeros(x.size, bool)
    rapid[len(XA)] = True
    return q, rapid


def _limit(sd):
    """A limit between the standard errors of the last node of contour A and every other node."""
    a_last = sd[len(XA) - 1]
    rest = np.delete(sd, len(XA) - 1)
    assert a_last > rest.max() * 1.1
    return 0.5 * (a_last + rest.max())


def test_one_node_over_the_limit_leaves_its_whole_contour_uncorrected():
    machine, fitted = _fitted(40.0)
    q, rapid = _two_contours()
    sd_oracle = _sd_oracle(fitted, q)
    limit = _limit(sd_oracle)
    problem = CompensationProblem.from_machine(fitted)
    res = plan_arrays(problem, q, feed=np.full(q.shape[0], 1000.0), rapid=rapid,
                      options=PlannerOptions(threads=1, max_correction_sd_um=limit))
    np.testing.assert_allclose(res.sd_um, sd_oracle, rtol=1e-6, atol=1e-9)
    a = np.arange(len(XA))
    b = np.arange(len(XA) + 1, q.shape[0])
    # every node of A uncorrected (one by its own standard error, the others by their contour's)
    assert res.pinned[a].all()
    np.testing.assert_array_equal(res.gated[a], [True, True, True, True, False])
    np.testing.assert_allclose(res.correction[a], 0.0, rtol=0, atol=0)
    # contour B and the rapid corrected: the tip lands where the program meant it (EXX only)
    assert not res.pinned[b].any() and not res.pinned[len(XA)] and not res.gated[b].any()
    want = -40e-3 * q[b, 0] / 1000.0                       # mm: minus the X error, 40 um per m
    np.testing.assert_allclose(res.correction[b, 0], want, rtol=0, atol=1e-4)
    np.testing.assert_allclose(res.after[b], 0.0, rtol=0, atol=1e-4)


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _program(tmp_path):
    lines = ["G21 G90", f"G0 X{XA[0]:.1f} Y0 Z0"]
    lines += [f"G1 X{x:.1f} F1000" for x in XA[1:]]
    lines += ["G0 Z10", f"G0 X{-50.0:.1f}", "G0 Z0"]      # a rapid between the contours
    lines += [f"G1 X{x:.1f} F1000" for x in XB]
    lines += ["G0 Z10", "M30"]
    prog = tmp_path / "two.nc"
    prog.write_text("\n".join(lines) + "\n")
    return prog


def test_compensate_leaves_the_contour_uncorrected_says_so_and_marks_it(tmp_path, capsys):
    machine, fitted = _fitted(40.0)
    q, _ = _two_contours()
    limit = _limit(_sd_oracle(fitted, q))
    path = tmp_path / "M.json"
    save_model(path, fitted)
    prog = _program(tmp_path)
    capsys.readouterr()
    assert main(["compensate", "xfyz", str(path), str(prog), "-o", str(tmp_path / "o.nc"),
                 "--report", str(tmp_path / "B.csv"), "--json", str(tmp_path / "S.json"),
                 "--max-correction-sd-um", f"{limit:.6f}", "--subdivide-tol-um", "0"]) == 0
    out = capsys.readouterr().out
    rows = [r for r in _rows(tmp_path / "B.csv") if r["unknown_axes"] == ""]
    feed_a = [r for r in rows if r["rapid"] == "0" and float(r["x_mm"]) > 0]
    feed_b = [r for r in rows if r["rapid"] == "0" and float(r["x_mm"]) < 0]
    # contour A: its first node is the G0's end (a rapid, own rule); its feed moves end at XA[1:]
    assert [float(r["x_mm"]) for r in feed_a] == XA[1:]
    assert all(r["corrected"] == "0" and r["uncertain"] == "1" for r in feed_a)
    assert all(float(r["cx_um"]) == 0.0 for r in feed_a)
    assert len(feed_b) == len(XB) and all(r["corrected"] == "1" and r["uncertain"] == "0"
                                          for r in feed_b)
    np.testing.assert_allclose([float(r["cx_um"]) for r in feed_b],
                               [-0.04 * x for x in XB], rtol=0, atol=0.06)
    # over the limit on their own: A's last feed node and the rapid up from it (its own rule)
    own = [r for r in rows if float(r["correction_sd_um"]) > limit]
    assert [(r["rapid"], float(r["x_mm"])) for r in own] == [("0", 250.0), ("1", 250.0)]
    assert "2 blocks not corrected: the model is unsure there" in out
    assert "and 3 blocks of the same contours" in out
    summary = json.loads((tmp_path / "S.json").read_text())
    assert summary["uncorrected"]["uncertain"] == 2
    assert summary["uncorrected"]["uncertain_contour"] == 3


def _dent_um(c):
    """The deepest interior local minimum of |correction| c along a contour: per node how far it
    lies below the smaller of the largest values before and after it (0 for all-or-nothing)."""
    c = np.abs(np.asarray(c, dtype=float))
    depth = [min(c[:i].max(), c[i + 1:].max()) - c[i] for i in range(1, c.size - 1)]
    return max(0.0, max(depth))


def _loop_program(tmp_path):
    """One contour: out along Y0 to x = 300 mm and back along Y50 (|X error| largest mid-contour)."""
    xs = np.arange(20.0, 300.0 + 1e-9, 10.0)
    lines = ["G21 G90", "G0 X20 Y0 Z0"]
    lines += [f"G1 X{x:.1f} F1000" for x in xs[1:]]
    lines += ["G1 Y50"]
    lines += [f"G1 X{x:.1f}" for x in xs[::-1][1:]]
    lines += ["G0 Z10", "M30"]
    prog = tmp_path / "loop.nc"
    prog.write_text("\n".join(lines) + "\n")
    return prog


@pytest.mark.parametrize("chunk_rows", [None, 7])
def test_a_contour_straddling_the_limit_is_cut_without_a_dent(tmp_path, monkeypatch, capsys,
                                                              chunk_rows):
    """200 um per m: 60 um at x = 300 mm; the standard error crosses the limit at x = 220 mm,
    mid-contour. Per node the gate left x > 220 mm uncorrected between corrections of 44 um, a
    dent ramped at 5 um a block; per contour nothing is corrected. With chunks of 7 rows the
    contour spans many chunks (held back until its end)."""
    if chunk_rows:
        monkeypatch.setattr(mtcomp.compensation, "CHUNK_ROWS", chunk_rows)
    machine, fitted = _fitted(200.0)
    limit = float(_sd_oracle(fitted, np.array([[220.0, 0.0, 0.0]]))[0])
    path = tmp_path / "M.json"
    save_model(path, fitted)
    prog = _loop_program(tmp_path)
    assert main(["compensate", "xfyz", str(path), str(prog), "-o", str(tmp_path / "o.nc"),
                 "--report", str(tmp_path / "B.csv"), "--max-correction-sd-um", f"{limit:.6f}",
                 "--quiet"]) == 0
    rows = [r for r in _rows(tmp_path / "B.csv") if r["unknown_axes"] == "" and r["rapid"] == "0"]
    sd = np.array([float(r["correction_sd_um"]) for r in rows])
    assert (sd > limit).any() and (sd < 0.5 * limit).any()     # the contour straddles the limit
    cx = [float(r["cx_um"]) for r in rows]
    assert _dent_um(cx) <= 5.0                                 # the step bound's one step at most
    assert {r["corrected"] for r in rows} == {"0"} and {r["uncertain"] for r in rows} == {"1"}
    # the same model with a limit above every node: the whole contour corrected, no dent either
    assert main(["compensate", "xfyz", str(path), str(prog), "-o", str(tmp_path / "o2.nc"),
                 "--report", str(tmp_path / "B2.csv"), "--max-correction-sd-um", "100",
                 "--quiet"]) == 0
    rows2 = [r for r in _rows(tmp_path / "B2.csv") if r["unknown_axes"] == "" and r["rapid"] == "0"]
    cx2 = np.array([float(r["cx_um"]) for r in rows2])
    assert {r["corrected"] for r in rows2} == {"1"} and _dent_um(cx2) <= 0.1
    np.testing.assert_allclose(cx2.min(), -50.0, rtol=0, atol=0.01)   # up to the 50 um bound


def test_the_dent_measure_sees_a_dent():
    assert _dent_um([0, 10, 20, 30, 25, 0, 0, 5, 30, 20]) == pytest.approx(30.0, rel=0, abs=1e-12)
    assert _dent_um([10, 20, 30, 30, 20, 10]) == 0.0


@pytest.mark.parametrize("limit_at_x", [220.0, None])
def test_contours_across_chunks_are_planned_as_in_one_piece(tmp_path, monkeypatch, limit_at_x):
    """The loop and the two contours in one program ending on a feed move (the last contour still
    open when the program ends), read 5 rows at a time: the same BLOCKS.csv and output as in one
    chunk, with the limit crossed in the loop (held back, then left uncorrected, then continued
    uncorrected) and with no block over it (held back to the program's end, then corrected)."""
    machine, fitted = _fitted(200.0)
    limit = 100.0 if limit_at_x is None else \
        float(_sd_oracle(fitted, np.array([[limit_at_x, 0.0, 0.0]]))[0])
    path = tmp_path / "M.json"
    save_model(path, fitted)
    loop = _loop_program(tmp_path).read_text().splitlines()[:-2]        # no G0 Z10, M30
    two = _program(tmp_path).read_text().splitlines()[1:-2]
    prog = tmp_path / "both.nc"
    prog.write_text("\n".join(loop + ["G0 Z10"] + two) + "\n")
    outs = []
    for rows in (None, 5):
        if rows:
            monkeypatch.setattr(mtcomp.compensation, "CHUNK_ROWS", rows)
        o, b = tmp_path / f"o{rows}.nc", tmp_path / f"b{rows}.csv"
        assert main(["compensate", "xfyz", str(path), str(prog), "-o", str(o), "--report", str(b),
                     "--max-correction-sd-um", f"{limit:.6f}", "--quiet"]) == 0
        outs.append((o.read_text(), b.read_text()))
    assert outs[0] == outs[1]
    rows = [r for r in _rows(tmp_path / "b5.csv") if r["unknown_axes"] == "" and r["rapid"] == "0"]
    corrected = {r["corrected"] for r in rows}
    assert corrected == ({"0", "1"} if limit_at_x else {"1"})


@pytest.mark.parametrize("flank", [None, 10.0])
def test_render_leaves_out_the_contours_the_planner_leaves_out(tmp_path, flank):
    """render without a report guesses which blocks compensate leaves uncorrected by the planner's
    rules: with the default limit (5 um) between the standard error at x = 250 mm and at 200 mm,
    contour A's every block is marked uncertain (3), contour B's none; as compensate's BLOCKS.csv.
    X's slope 100 um per m at a standard error of 24 (the scale below): B's corrections are told
    from zero (4.2 standard errors; at 40 um per m, 1.7, compensate leaves B too)."""
    from mtcomp.planner.problem import DEFAULT_MAX_CORRECTION_SD_UM as limit
    from mtcomp.viz.surface import program_error_map
    machine, fitted = _fitted(100.0)
    q, _rapid = _two_contours()
    scale = 1.2 * limit / _sd_oracle(fitted, q)[len(XA) - 1]        # sd(250 mm) = 1.2 x the limit
    fitted.uncertainty["covariance"] = fitted.uncertainty["covariance"] * scale ** 2
    sd = _sd_oracle(fitted, q) * scale                                # SIGMA scaled alike
    assert sd[len(XA) - 1] > limit > np.delete(sd, len(XA) - 1).max()
    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z0\n" + "".join(f"G1 X{x:g} F1000\n" for x in XA)
                    + "G0 X-50\n" + "".join(f"G1 X{x:g}\n" for x in XB) + "M30\n")
    # a path map: one point a block; a flank map (a 10 mm flank): each block's point at every level
    smap = (program_error_map(machine, fitted, prog, tool_radius_mm=0.0, normal="path") if flank is None
            else program_error_map(machine, fitted, prog, tool_radius_mm=1.0, flank_length_mm=flank))
    assert smap.status_source == "planner"
    x = np.round(smap.tips[:, 0], 3)               # the nominal tip of each point's block
    in_a = (x > 1.0) & np.isin(np.round(x, 3), XA)
    in_b = np.isin(np.round(x, 3), XB)
    assert in_a.sum() >= 4 and in_b.sum() >= 3
    assert np.all(smap.status[in_a] == 3) and np.all(smap.status[in_b] == 0)
