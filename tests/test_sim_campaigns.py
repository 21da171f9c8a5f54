"""The virtual machine: SPEC files that read back to what the measurement models predict, plans that
follow their standards, realistic random truths."""
import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp import sim
from mtcomp.measurement.readings import model_class_for
from mtcomp.measurement.drift import drift_context
from mtcomp.measurement.files import read_measurements
from mtcomp.models import AbbeIRC, Backlash, ChannelDrift, FeedOffset, PeriodicError, ThermalDrift

SPEC_COLUMNS = {
    "points": {"x_mm", "y_mm", "z_mm"},
    "laser": {"axis", "component", "dir", "run"},
    "ballbar": {"x_mm", "y_mm", "z_mm", "table_ball_x_mm", "table_ball_y_mm", "table_ball_z_mm",
                "tool_ball_x_mm", "tool_ball_y_mm", "tool_ball_z_mm", "length_mm"},
    "thermal": {"t_s"},
    "velocity": {"axis", "feed_mm_min", "m_x_mm", "m_y_mm", "m_vx_mm_min", "m_vy_mm_min", "n_x_mm",
                 "n_y_mm", "n_vx_mm_min", "n_vy_mm_min"},
}


def all_plans(m):
    plans = [sim.iso230_2_plan(m, "X", components=("EXX", "EYX", "ECX"), n_runs=2),
             sim.volumetric_points_plan(m, n_per_axis=(3, 3, 2)),
             sim.ballbar_circles_plan(m, n_points=24),
             sim.thermal_plan(m, duration_h=2.0, interval_s=300.0, channels=("x", "z", "ch1")),
             sim.velocity_plan(m, n_runs=1, feeds_mm_min=(240.0,))]
    if m.is_five_axis:
        plans += [sim.three_sphere_plan(m, angles_deg=np.arange(0, 360, 60), n_runs=1),
                  sim.rotary_laser_plan(m, n_runs=2)]
    return plans


def truth_terms(m):
    return [Backlash("X"), PeriodicError("Y", 16.0), FeedOffset("Z"),
            AbbeIRC("X", angles="C", static=True, feed=True), ThermalDrift("time", ("time_h",)),
            ThermalDrift("spindle", ("spindle_heat_900",)),
            ChannelDrift("spindle_ch", ("spindle_heat_900",), ("ch1",))]


@pytest.mark.parametrize("name", ["xfyz", "cafxyz"])
def test_files_read_back_to_the_measurement_models(name, tmp_path):
    m = load_machine(name)
    truth = sim.random_truth(m, np.random.default_rng(1), terms=truth_terms(m))
    vm = sim.VirtualMachine(m, truth, noise_um=0.0, noise_urad=0.0, noise_velocity_mm_min=0.0)
    out = vm.campaign(all_plans(m), tmp_path, noise=False)
    for plan in all_plans(m):
        path = tmp_path / f"{plan.name}.csv"
        data = read_measurements(path)                  # the kind is told by the columns alone
        assert data.kind == plan.kind
        header = open(path).readline().strip().split(",")
        assert SPEC_COLUMNS[plan.kind] <= set(header) | {c for c in header if c.startswith("disp_")}
        got = out[plan.name]
        mm = model_class_for(plan.kind)(truth.model, got, truth.context_defaults, machine=m,
                                        extra_context=drift_context(truth.model, got))
        pred = mm.predict_columns(truth.params.values, mm.zero_nuisance())
        assert mm.n_obs > 0
        # the observations in the file are the model's prediction (10 significant digits in the CSV)
        np.testing.assert_allclose(mm.observed, mm.predict(truth.params.values, mm.zero_nuisance()),
                                   rtol=1e-8, atol=1e-12)
        for col in plan.measured:
            assert f"pred_{col}" in pred


def test_noise_has_the_requested_size(tmp_path):
    m = load_machine("xfyz")
    truth = sim.random_truth(m, np.random.default_rng(4))
    plan = sim.volumetric_points_plan(m, n_per_axis=(6, 6, 5))
    quiet = sim.VirtualMachine(m, truth, noise_um=0.0).measure(plan)
    noisy = sim.VirtualMachine(m, truth, noise_um=0.5, rng=np.random.default_rng(9)).measure(
        plan, tmp_path / "p.csv")
    diff = (noisy.deviation - quiet.deviation) * 1e3
    assert diff.size == 3 * 360
    np.testing.assert_allclose(diff.std(), 0.5, rtol=0.08, atol=0)
    np.testing.assert_allclose(diff.mean(), 0.0, rtol=0, atol=0.06)


def test_iso230_2_plan_is_the_standard_cycle():
    m = load_machine("xfyz")
    plan = sim.iso230_2_plan(m, "Y")
    targets = np.unique(plan.columns["target_mm"])
    lo, hi = m.axis("Y").travel
    assert len(targets) >= 5 and lo < targets.min() and targets.max() < hi
    steps = np.diff(targets)
    assert steps.std() > 0.01 * steps.mean()           # irregular spacing
    runs, dirs = plan.columns["run"], plan.columns["dir"]
    assert set(runs) == {1, 2, 3, 4, 5}
    for r in range(1, 6):
        for d in (1, -1):
            sel = (runs == r) & (dirs == d)
            assert sel.sum() == len(targets)
            order = plan.columns["target_mm"][sel]
            assert np.all(np.diff(order) * d > 0)        # up through the targets, then down
    t = plan.columns["t_s"]
    assert np.all(np.diff(t) > 0)


def test_campaign_time_runs_on(tmp_path):
    m = load_machine("xfyz")
    vm = sim.VirtualMachine(m, sim.random_truth(m, np.random.default_rng(0)), rng=1)
    plans = [sim.iso230_2_plan(m, "X", n_runs=1), sim.ballbar_circles_plan(m, n_points=12)]
    out = vm.campaign(plans, tmp_path, gap_s=100.0)
    t1, t2 = out[plans[0].name].context.t, out[plans[1].name].context.t
    assert t2.min() >= t1.max() + 100.0


def test_ballbar_circle_directions_follow_the_motion():
    m = load_machine("xfyz")
    plan = sim.ballbar_circles_plan(m, planes=("XY",), senses=("ccw",), n_points=8)
    x, y = plan.columns["x_mm"], plan.columns["y_mm"]
    # CCW from angle 0: x decreases (dir -1) over the upper half circle, y increases at the start
    np.testing.assert_array_equal(plan.columns["dir_x"][1:4], [-1, -1, -1])
    np.testing.assert_array_equal(plan.columns["dir_y"][1:2], [1])
    np.testing.assert_allclose(np.hypot(x - x.mean(), y - y.mean()), 100.0, rtol=0, atol=1e-9)


def test_random_truth_has_machine_tool_size():
    m = load_machine("xfyz")
    truth = sim.random_truth(m, np.random.default_rng(7))
    data = sim.VirtualMachine(m, truth, noise_um=0.0).measure(sim.volumetric_points_plan(m))
    dev_um = np.abs(data.deviation) * 1e3
    assert 3.0 < dev_um.max() < 300.0
    sq = np.abs([truth.params[n] for n in ("C0Y", "B0Z", "A0Z")]) * 1e6
    assert sq.max() < 150.0 and sq.max() > 1.0


def test_measure_refuses_a_missing_folder(tmp_path):
    from mtcomp.errors import InputError
    m = load_machine("xfyz")
    vm = sim.VirtualMachine(m, sim.random_truth(m, np.random.default_rng(0)))
    with pytest.raises(InputError, match="does not exist"):
        vm.campaign([sim.iso230_2_plan(m, "X", n_runs=1)], tmp_path / "nope")
