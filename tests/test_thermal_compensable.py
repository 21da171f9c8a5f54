"""A thermal record whose drift a settling time and the temperatures predict alike: the drift on
temperatures, which compensate can follow, is kept (a quality engineer's 4 h warm-up with 0.5 h cut
out of it was given a settling drift in time, 0.223 um forward against 0.221 um for the
temperatures, and compensate --temperature was then refused).

The record is written here with numpy alone: two sensors that warm up as 1 - exp(-t / tau), the
tip drifting linearly with them (X, Y, Z), noise 0.2 um, readings every 20 s for 4 h."""
import numpy as np

from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from mtcomp.thermal import diagnose_thermal
from mtcomp.thermal._fit import CandidateScore, alike_z, choose, fit_thermal


def _record(path, seed, gap=True):
    rng = np.random.default_rng(seed)
    t = np.arange(0, 4 * 3600 + 1, 20.0)
    th_true = 20 + 12 * (1 - np.exp(-t / 2400))
    tc_true = 20 + 4 * (1 - np.exp(-t / 6000))
    th = th_true + rng.normal(0, 0.05, t.size)
    tc = tc_true + rng.normal(0, 0.05, t.size)
    dx = 1.0 * (th_true - 20)
    dy = 0.1 * (tc_true - 20)
    dz = -1.2 * (th_true - 20) - 0.1 * (tc_true - 20)
    d = np.column_stack([dx, dy, dz]) + rng.normal(0, 0.2, (t.size, 3))
    keep = ~((t > 3600) & (t < 5400)) if gap else np.ones(t.size, dtype=bool)
    lines = ["t_s,spindle_rpm,temp_head_c,temp_column_c,disp_x_um,disp_y_um,disp_z_um"]
    lines += [f"{t[i]:.0f},8000,{th[i]:.3f},{tc[i]:.3f},{d[i, 0]:.3f},{d[i, 1]:.3f},{d[i, 2]:.3f}"
              for i in np.flatnonzero(keep)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_temperatures_kept_where_a_drift_in_time_predicts_alike(tmp_path):
    fit = fit_thermal(read_measurements(_record(tmp_path / "gap.csv", seed=1)))
    by = {s.label: s for s in fit.scores}
    settling, temps = by["settling drift in time"], by["temperatures"]
    # the settling drift predicts a little better (the temperatures carry their sensors' noise), by
    # less than two standard errors of the difference: alike; the parsimony rule alone kept it
    assert settling.total_sse < temps.total_sse
    assert -2.0 < alike_z(settling, temps) < 0.0
    assert fit.chosen is temps, [(s.label, s.total_sse) for s in fit.scores]
    words = diagnose_thermal(load_machine("xfyz"), read_measurements(tmp_path / "gap.csv")).findings[0].evidence
    assert "settling drift in time predicts it alike" in words and "Diebold and Mariano 1995" in words


def test_a_drift_in_time_clearly_better_stays_and_is_said_unusable(tmp_path):
    path = _record(tmp_path / "gap14.csv", seed=14)
    d = diagnose_thermal(load_machine("xfyz"), read_measurements(path))
    by = {s.label: s for s in d.thermal.scores}
    # the temperatures' sensor noise costs them more than 2 standard errors here: time is kept
    assert alike_z(by["temperatures"], by["settling drift in time"]) > 2.0
    assert d.thermal.chosen.driver == "time"
    assert "compensate cannot use a drift in time" in d.findings[0].evidence
    assert "temperatures, which it could use, predicts the record" in d.findings[0].evidence


def test_alike_z_on_a_hand_made_loss_differential():
    """d_t = 1 + 0.5 (-1)^t over 100 readings (lag-1 autocorrelation -1, taken as 0): the sum 100 over
    sqrt(100 * 0.25 * 100 / 99) = 5.025 standard errors, 19.90."""
    n = 100
    d = 1.0 + 0.5 * (-1.0) ** np.arange(n)
    a = CandidateScore("a", "temperature", ["temperature"], [], 4,
                       forward_err=np.sqrt(d + 1.0)[:, None])
    b = CandidateScore("b", "time", ["time"], [], 2, forward_err=np.ones((n, 1)))
    np.testing.assert_allclose(alike_z(a, b), 100.0 / np.sqrt(100 * 0.25 * 100 / 99), rtol=1e-9)
    # a time drift clearly better than the temperatures stays chosen
    a.forward_sse, b.forward_sse = np.array([np.sum(d + 1.0)]), np.array([float(n)])
    assert choose([a, b]) is b


def test_the_drift_finding_names_every_direction_it_holds(tmp_path):
    """The finding was 'thermal_drift on Z' (the channel that drifts most) although X and Y are
    fitted and corrected too: it names X, Y and Z, each with its largest drift since the first
    reading, computed here from the file."""
    path = _record(tmp_path / "full.csv", seed=1, gap=False)
    d = diagnose_thermal(load_machine("xfyz"), read_measurements(path))
    f = d.findings[0]
    rows = np.loadtxt(path, delimiter=",", skiprows=1)
    drift = np.max(np.abs(rows[:, 4:7] - rows[0, 4:7]), axis=0)
    assert f.params["directions"] == ["X", "Y", "Z"]
    got = f.params["drift_range_by_direction_um"]
    np.testing.assert_allclose([got[a] for a in "XYZ"], drift, rtol=0, atol=1e-3)
    assert f.axis == "Z" and f.params["direction"] == "Z"      # the contract's keys, unchanged
    assert "1. thermal_drift on X, Y, Z:" in d.summary()
