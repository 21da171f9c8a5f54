"""identify(): recovery of known parameters (noise-free to 1e-8, with noise within the standard
errors and standard errors that match the scatter over seeds), joint fits of mixed files, rank
deficiency named, extension parameters, weighting, the result object."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.identification.fit import identify
from mtcomp.measurement.readings import measurement_model
from mtcomp.machine import load_machine
from mtcomp.models import Backlash, ErrorModel, FittedModel, ParameterSet
from mtcomp.sim import make_laser, make_points, random_campaign, random_parameters, simulate

@pytest.fixture(scope="module")
def xfyz():
    """The built-in 3-axis machine on the polynomial basis: these tests recover parameters of
    mtcomp's own model by name (EXX_1 ...) from its own simulator (the independent machine's tests
    are in test_identify_independent.py)."""
    m = load_machine("xfyz").with_basis("polynomial")
    return m, ErrorModel(m)


@pytest.fixture(scope="module")
def cafxyz():
    m = load_machine("cafxyz").with_basis("polynomial")
    return m, ErrorModel(m)


def _file(model, values):
    """Parameter values in file units (um, urad)."""
    return values * np.array([s.to_file for s in model.param_specs])


def _machine_with_degree(machine, degree):
    axes = tuple(dataclasses.replace(a, degree=degree) if not a.is_rotary else a for a in machine.axes)
    return dataclasses.replace(machine, axes=axes)


def test_noise_free_rich_campaign_recovers_parameters(xfyz):
    machine, model = xfyz
    rng = np.random.default_rng(10)
    camp = random_campaign(machine, rng)
    free = model.base_mask.copy()
    p = random_parameters(model, rng, mask=free)
    data = [simulate(model, d, p) for d in camp.values()]
    res = identify(model, data)
    assert res.rank == res.n_params == free.sum() + sum(len(s) for s in [res.nuisance_specs])
    assert res.undetermined == []
    assert res.converged and res.iterations <= 5
    # 1e-8 relative to the parameter sizes (10 um, 20 urad)
    np.testing.assert_allclose(_file(model, res.values), _file(model, p), rtol=1e-8, atol=1e-7)
    np.testing.assert_allclose(res.nuisance_values, 0.0, rtol=0, atol=1e-10)
    for f in res.files:
        assert max(f.rms().values()) < 1e-6


def test_joint_fit_points_laser_ballbar_five_axis_with_nuisance(cafxyz):
    machine, model = cafxyz
    rng = np.random.default_rng(11)
    camp = random_campaign(machine, rng, n_points=250)
    free = model.base_mask.copy()
    p = random_parameters(model, rng, mask=free)
    mms = {k: measurement_model(model, d) for k, d in camp.items()}
    nuis = {k: rng.normal(size=m.n_nuisance) * 1e-3 for k, m in mms.items()}
    data = [simulate(model, camp[k], p, nuis[k]) for k in camp]
    res = identify(model, data)
    assert res.undetermined == [] and res.rank == res.n_params
    # 1e-8 relative to the parameter sizes (10 um, 20 urad)
    np.testing.assert_allclose(_file(model, res.values), _file(model, p), rtol=1e-8, atol=1e-7)
    np.testing.assert_allclose(res.nuisance_values, np.concatenate([nuis[k] for k in camp]),
                               rtol=1e-8, atol=1e-11)
    assert [f.kind for f in res.files] == ["points", "laser", "ballbar"]
    # the fitted model predicts the data
    mm = measurement_model(model, data[0])
    setup = res.nuisance_values[:mm.n_nuisance]     # the points file's own set-up (zero here)
    np.testing.assert_allclose(mm.predict(res.fitted_model.params.values, setup), mm.observed,
                               rtol=0, atol=1e-9)


def test_rich_campaign_determines_the_whole_base_model(xfyz):
    """The base model has no built-in redundancy: the straightness slopes that a squareness carries
    (EXY_1 ~ C0Y ...) are not in it (ISO 230-1), so a rich campaign determines every parameter."""
    machine, model = xfyz
    rng = np.random.default_rng(12)
    camp = random_campaign(machine, rng, n_points=200)
    p = random_parameters(model, rng)
    res = identify(model, [simulate(model, d, p) for d in camp.values()])
    assert res.undetermined == [] and res.determined[model.base_mask].all()
    assert "EXY_1" not in model.param_names and "C0Y" in model.param_names
    np.testing.assert_allclose(_file(model, res.values), _file(model, p), rtol=1e-8, atol=1e-7)
    assert "every fitted parameter is determined by the data" in res.summary()


def test_undetermined_direction_resolved_by_the_data_not_the_truth(xfyz):
    """Points at one Z level cannot see EXX_1 + 1 um against EBX_1 - 20 urad (50 mm Abbe arm): truth
    moved along that direction gives the same estimates (what the data leave open is resolved by a
    rule, the least predicted error over the travel, never by where the truth lies), and the summary
    names it."""
    machine, model = xfyz
    rng = np.random.default_rng(14)
    xyz = rng.uniform([-400, -300, 0], [400, 300, 0], (300, 3))
    xyz[:, 2] = 50.0
    clean = make_points(xyz)
    p = random_parameters(model, rng)
    res = identify(model, [simulate(model, clean, p)])
    names = list(model.param_names)
    i, j = names.index("EXX_1"), names.index("EBX_1")
    assert not res.determined[i] and not res.determined[j] and np.isnan(res.std_errors[i])
    p2 = p.copy()
    p2[i] += 0.25e-3   # 0.25 um per metre
    p2[j] -= 5e-6      # 5 urad per metre: 50 mm * 5 urad = 0.25 um
    res2 = identify(model, [simulate(model, clean, p2)])
    # up to second-order effects (5 urad x tens of urad x arms of ~500 mm ~ 1e-3, and 5e-5 of the
    # largest parameters); a fit that moved with the truth would shift EXX_1 by 0.25 and EBX_1 by 5
    np.testing.assert_allclose(_file(model, res2.values), _file(model, res.values), rtol=5e-5, atol=3e-3)
    text = res.summary()
    assert "EXX_1" in text and "EBX_1" in text and "cannot determine" in text


def test_a_laser_run_of_x_alone_invents_no_error_of_axes_it_never_moved(tmp_path):
    """A positioning run of X (Y, Z, the tool never changed): the readings' constant is shared, in the
    data, by the laser's zero offset, the pitch of Z (through its 12.5 mm arm) and the squareness B0S
    (through the tool). It is the offset's: the model predicts the same X error for every tool length
    and every Z, as the data say nothing of them (the plain minimum-norm split had put 105 urad in EBZ
    and 13 urad in B0S, 2.6 um more X error per 100 mm of tool). Data from the independent machine."""
    import csv
    from mtcomp.cli import main
    from truth import TruthMachine
    from truth import campaigns as tc
    rng = np.random.default_rng(5)
    m = TruthMachine.random("xfyz", rng, effects=[], error_motions=False)
    laser = tc.laser(m, tmp_path / "x1.csv", rng, "X", components=("EXX",), targets=np.linspace(-200, 200, 11),
                     n_runs=3, feed_mm_min=[1000.0], noise_um=0.3, t0_s=0.0).path
    assert main(["identify", "xfyz", str(laser), "-o", str(tmp_path / "m.json")]) == 0
    rows = ["x_mm,y_mm,z_mm,tool_mm,dx_um"] + [f"{x},0,{z},{t},0" for x in (-200, 0, 150)
                                             for z in (-200, 0, 100) for t in (0, 100, 250)]
    (tmp_path / "p.csv").write_text("\n".join(rows) + "\n")
    assert main(["predict", "xfyz", str(tmp_path / "m.json"), str(tmp_path / "p.csv"), "-o",
                 str(tmp_path / "pred.csv")]) == 0
    with open(tmp_path / "pred.csv") as f:
        pred = list(csv.DictReader(f))
    by_x = {}
    for r in pred:
        by_x.setdefault(float(r["x_mm"]), []).append(float(r["pred_dx_um"]))
    for x, v in by_x.items():
        assert np.ptp(v) < 1e-3, (x, v)             # one X error whatever the tool and Z
    assert len({round(v[0], 3) for v in by_x.values()}) == 3       # the profile along X is kept


def test_points_at_one_z_level_name_abbe_combinations(xfyz):
    machine, model = xfyz
    rng = np.random.default_rng(13)
    xyz = rng.uniform([-400, -300, 0], [400, 300, 0], (300, 3))
    xyz[:, 2] = 50.0
    data = simulate(model, make_points(xyz), random_parameters(model, rng))
    res = identify(model, [data], known_setup=[data.path])    # simulated in the workpiece frame
    assert res.rank < res.n_params
    # X table pitch EBX about the workpiece origin moves a tip 50 mm above it by 50 mm * EBX along x:
    # EXX_1 + 1 um with EBX_1 - 20 urad leaves every reading unchanged
    found = {tuple(sorted(u.names)): dict(u.terms) for u in res.undetermined}
    assert ("EBX_1", "EXX_1") in found
    coef = found[("EBX_1", "EXX_1")]
    np.testing.assert_allclose(coef["EBX_1"] / coef["EXX_1"], -20.0, rtol=1e-6, atol=0)
    # every named direction is a null direction of the prediction (independent check via predict)
    mm = measurement_model(model, data)
    J, _ = mm.jacobian(res.values, None)
    names = list(model.param_names)
    for u in res.undetermined:
        v = np.zeros(model.n_params)
        for n, c in u.terms:
            v[names.index(n)] = c / model.param_specs[names.index(n)].to_file
        # one file unit (1 um or 1 urad on the pivot) along it moves no reading by 1 nm
        assert np.abs(J @ v).max() < 1e-6, str(u)


def test_noise_estimates_within_standard_errors_and_errors_match_scatter():
    machine = _machine_with_degree(load_machine("xfyz").with_basis("polynomial"), 2)
    model = ErrorModel(machine)
    rng0 = np.random.default_rng(20)
    lo, hi = machine.travel_bounds()
    xyz = rng0.uniform(lo, hi, (200, 3))
    tool = rng0.choice([0.0, 100.0, 250.0], 200)
    hold = [n for n in model.param_names if n.startswith(("ECY", "ECZ"))]
    free = model.base_mask & ~np.isin(model.param_names, hold)
    p = random_parameters(model, rng0, mask=free)
    clean = make_points(xyz, tool=tool)
    noise_um = 0.5
    z, est, se = [], [], []
    for seed in range(50):
        data = simulate(model, clean, p, noise_um=noise_um, rng=np.random.default_rng(100 + seed))
        res = identify(model, [data], hold=hold, known_setup=[data.path])
        est.append(res.values[free])
        se.append(res.std_errors[free])
        z.append((res.values[free] - p[free]) / res.std_errors[free])
    z, est, se = np.array(z), np.array(est), np.array(se)
    assert np.all(np.isfinite(z))
    # within 3 standard errors (99.7 %): allow the expected handful over 50 x n draws
    assert np.mean(np.abs(z) > 3) < 0.01
    assert np.abs(z).max() < 5
    # reported standard errors against the scatter over the seeds
    ratio = est.std(axis=0, ddof=1) / se.mean(axis=0)
    assert 0.8 < np.sqrt(np.mean(ratio ** 2)) < 1.2
    assert np.all((ratio > 0.6) & (ratio < 1.45))
    # sigma of unit weights (um) estimates the noise
    assert abs(res.sigma / noise_um - 1) < 0.15


def test_extension_parameters_fitted_when_asked(xfyz):
    machine, base = xfyz
    model = base.with_terms(Backlash("X"))
    rng = np.random.default_rng(14)
    n = 120
    target = np.tile(np.linspace(-400, 400, 20), 6)
    direction = np.repeat([1, -1, 1, -1, 1, -1], 20)
    data = make_laser(["X"] * n, ["EXX"] * n, target, direction)
    p = np.zeros(model.n_params)
    p[model.param_names.index("EXX_1")] = 8e-3
    p[model.param_names.index("EXX_2")] = -5e-3
    p[model.param_names.index("BL_X")] = 4e-3
    data = simulate(model, data, p)
    names = ["EXX_1", "EXX_2", "EXX_3", "BL_X"]
    res = identify(model, [data], free=names)
    assert res.undetermined == [] and res.rank == 5  # + the zero offset
    np.testing.assert_allclose(res.value("BL_X")[0], 4.0, rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(res.value("EXX_2")[0], -5.0, rtol=1e-8, atol=1e-9)
    assert not res.free[model.param_names.index("EYX_1")]
    with pytest.raises(InputError, match="NOPE"):
        identify(model, [data], free=["NOPE"])


def test_noise_weighting_per_file(xfyz):
    machine, model = xfyz
    rng = np.random.default_rng(15)
    camp = random_campaign(machine, rng, n_points=400)
    p = random_parameters(model, rng)
    pts = simulate(model, camp["points"], p, noise_um=0.2, rng=rng)
    las = simulate(model, camp["laser"], p, noise_um=2.0, noise_urad=4.0, rng=rng)
    res = identify(model, [pts, las], weights="noise")
    w = {f.tag: f for f in res.files}
    # weights 1/noise per file and unit: internal mm -> 1/um noise = 1e3 / noise_um
    np.testing.assert_allclose(np.median(w["points"].weight), 1e3 / 0.2, rtol=0.1, atol=0)
    las_w = w["laser"].weight
    um = np.array([c == "value_um" for c in w["laser"].columns])
    np.testing.assert_allclose(np.median(las_w[um]), 1e3 / 2.0, rtol=0.15, atol=0)
    np.testing.assert_allclose(np.median(las_w[~um]), 1e6 / 4.0, rtol=0.15, atol=0)
    assert abs(res.sigma - 1) < 0.1
    # the joint estimates sit within their standard errors (99.7 % within 3)
    z = (res.values - p)[res.determined] / res.std_errors[res.determined]
    assert np.mean(np.abs(z) > 3) < 0.03 and np.abs(z).max() < 5
    assert 0.7 < np.sqrt(np.mean(z ** 2)) < 1.3
    res_dict = identify(model, [pts, las], weights={"points": 0.2, "laser": 2.0})
    assert "given noise" in res_dict.weighting
    with pytest.raises(InputError, match="nothere"):
        identify(model, [pts], weights={"nothere": 1.0})


def test_result_reports_per_file_residuals_in_file_units(xfyz):
    machine, model = xfyz
    rng = np.random.default_rng(16)
    xyz = rng.uniform(-200, 100, (60, 3))
    dev = np.full((60, 3), np.nan)
    dev[:, 2] = 0.0
    data = make_points(xyz, deviation=dev, path="probe.csv")
    data = simulate(model, data, np.zeros(model.n_params))
    # one outlier of +7 um in row 5
    bad = data.deviation.copy()
    bad[5, 2] += 7e-3
    data = dataclasses.replace(data, deviation=bad)
    res = identify(model, [data], free=["EZX_1", "EZY_1", "TOOL_dL"], known_setup=[data.path])
    f = res.files[0]
    assert f.tag == "probe" and f.n_obs == 60 and set(f.columns) == {"dz_um"}
    assert f.rows[np.argmax(np.abs(f.residual))] == 5 and f.file_rows[5] == 6
    # least squares with an intercept-like TOOL_dL: residuals sum to ~0, the outlier keeps most of 7 um
    assert 5.0 < f.residual[5] < 7.0
    np.testing.assert_allclose(f.rms()["dz_um"], np.sqrt(np.mean(f.residual ** 2)), rtol=1e-12, atol=0)
    corr = res.correlation
    np.testing.assert_allclose(np.diag(corr), 1.0, rtol=1e-12, atol=0)
    d = res.to_dict()
    assert d["n_obs"] == 60 and d["files"][0]["tag"] == "probe"


def test_start_from_fitted_model_keeps_held_values(xfyz):
    machine, model = xfyz
    rng = np.random.default_rng(17)
    camp = random_campaign(machine, rng, n_points=150)
    free = model.base_mask.copy()
    p = random_parameters(model, rng, mask=free)
    data = [simulate(model, d, p) for d in camp.values()]
    # the X errors are known (held at their true values), the rest is fitted
    held = [n for n in model.param_names if n.endswith("X_1") or n.endswith("X_2")]
    start = FittedModel(model, ParameterSet(model.param_specs, np.where(np.isin(model.param_names, held),
                                                                        p, 0.0)))
    res = identify(start, data, hold=held)
    idx = np.isin(model.param_names, held)
    np.testing.assert_array_equal(res.values[idx], p[idx])
    assert np.all(np.isnan(res.std_errors[idx])) and not res.free[idx].any()
    np.testing.assert_allclose(_file(model, res.values), _file(model, p), rtol=1e-8, atol=1e-7)


def test_no_degrees_of_freedom_gives_strict_json(xfyz):
    import json
    machine, model = xfyz
    # at the end of the travel one reading sees each straightness better than its own noise (at
    # x = 100 mm it would not: 0.1 of the parameter against 0.23 rms over the travel)
    data = simulate(model, make_points([[400.0, 0.0, 0.0]]), np.zeros(model.n_params))
    res = identify(model, [data], free=["EXX_1", "EYX_1", "EZX_1", "EXX_2"], known_setup=[data.path])
    assert res.rank == 3 and res.dof == 0 and np.isnan(res.sigma)
    assert [sorted(u.names) for u in res.undetermined] == [["EXX_1", "EXX_2"]]
    text = json.dumps(res.to_dict(), allow_nan=False)
    assert '"sigma": null' in text


def test_compare_f_test_against_a_hand_computation(xfyz):
    """A fit with a backlash term against the base fit of data with a real backlash: the F statistic
    recomputed by hand from the two weighted residual sums, and a tiny p-value; without a backlash in
    the data the extension is not significant."""
    from scipy import stats
    machine, model = xfyz
    rng = np.random.default_rng(19)
    ext = ErrorModel(machine, [Backlash("X")])
    x = rng.uniform(-300, 300, 200)
    dirs = rng.choice([-1.0, 1.0], 200)
    for bl, significant in ((4e-3, True), (0.0, False)):
        values = np.zeros(ext.n_params)
        values[ext.param_names.index("BL_X")] = bl
        data = make_laser(["X"] * 200, ["EXX"] * 200, x, direction=dirs)
        data = simulate(ext, data, values, noise_um=0.3, rng=np.random.default_rng(5))
        base = identify(model, [data])
        full = identify(ext, [data], free=list(model.param_names[i] for i in np.flatnonzero(model.base_mask))
                        + ["BL_X"])
        cmp = base.compare(full)
        F = ((base.cost - full.cost) / (full.rank - base.rank)) / (full.cost / full.dof)
        assert cmp["F"] == pytest.approx(F, rel=1e-12, abs=0)
        assert cmp["p_value"] == pytest.approx(stats.f.sf(F, full.rank - base.rank, full.dof), rel=1e-9)
        assert (cmp["p_value"] < 1e-6) == significant


def test_row_groups_numbers_rows_as_numpy_unique_does():
    from mtcomp.measurement.outliers import row_groups
    rng = np.random.default_rng(5)
    keys = rng.integers(0, 3, (500, 4)).astype(float) * np.array([1.0, 0.5, -2.0, 1e-6])
    expected = np.unique(keys, axis=0, return_inverse=True)[1].ravel()
    np.testing.assert_array_equal(row_groups(keys), expected)
    assert row_groups(np.zeros((0, 3))).size == 0


def test_chord_steps_reach_the_exact_least_squares_minimum(xfyz):
    """The fit reuses the start's normal matrix (chord steps with exact gradients); its optimum must
    be the exact one: a Gauss-Newton step from the result, on a Jacobian taken by central finite
    differences (not the model's), moves no determined parameter by more than 1e-3 of its standard
    error. Errors 30 times a real machine's, so the problem is not linear."""
    machine, model = xfyz
    rng = np.random.default_rng(11)
    lo, hi = machine.travel_bounds()
    q = rng.uniform(lo, hi, (400, 3))
    p = random_parameters(model, rng, mask=model.base_mask.copy()) * 30.0
    data = simulate(model, make_points(q, tool=rng.choice([0.0, 150.0], 400)), p, noise_um=0.5, rng=rng)
    res = identify(model, [data])
    mm = measurement_model(model, data)
    nuis = res.nuisance_values

    def resid(v, n):
        return mm.observed - mm.predict(v, n)

    idx = np.flatnonzero(res.determined)
    cols = []
    for i in idx:
        h = 1e-4 * res.std_errors[i]
        e = np.zeros_like(res.values)
        e[i] = h
        cols.append((resid(res.values - e, nuis) - resid(res.values + e, nuis)) / (2 * h))
    for k in range(nuis.size):
        h = 1e-6
        e = np.zeros_like(nuis)
        e[k] = h
        cols.append((resid(res.values, nuis - e) - resid(res.values, nuis + e)) / (2 * h))
    J = np.column_stack(cols)
    step = np.linalg.lstsq(J, resid(res.values, nuis), rcond=None)[0][:idx.size]
    ratio = np.abs(step) / res.std_errors[idx]
    assert ratio.max() < 1e-3, ratio.max()


def test_hold_by_name_component_axis_and_group():
    from mtcomp.identification.problem import _free_mask, held_parameters
    model = ErrorModel(load_machine("cafxyz"))
    groups = [s.group for s in model.param_specs]
    names = list(model.param_names)
    x = held_parameters(model, "X")
    assert x.sum() == sum(g.startswith("X:") for g in groups) > 0
    c = held_parameters(model, "C")
    assert c.sum() == sum(g.startswith("C:") for g in groups)
    assert all(held_parameters(model, "C")[names.index(n)] for n in ("X0C", "Y0C", "A0C", "B0C"))
    assert held_parameters(model, "EXX").sum() == groups.count("X:EXX")
    assert held_parameters(model, "squareness").sum() == 3
    assert held_parameters(model, "C:location").sum() == 4
    assert held_parameters(model, names[5]).sum() == 1
    mask = _free_mask(model, None, ["X", "squareness"])
    assert not mask[x].any() and mask[c].all()
    with pytest.raises(InputError, match="--hold Q: no such parameter"):
        _free_mask(model, None, ["Q"])
    with pytest.raises(InputError, match="did you mean squareness"):
        _free_mask(model, None, ["squarenes"])


def test_calibrated_ball_bar_has_no_length_offset():
    from mtcomp.identification.problem import build_measurement_models
    from mtcomp.sim import make_ballbar
    model = ErrorModel(load_machine("xfyz"))
    th = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    xyz = np.column_stack([100 * np.cos(th), 100 * np.sin(th), np.zeros_like(th)])
    data = make_ballbar(xyz, np.zeros((12, 3)), np.zeros((12, 3)), length=np.full(12, 100.0))
    (free,) = build_measurement_models(model, [data])
    (cal,) = build_measurement_models(model, [data], known_setup=[str(data.path)])
    assert free.n_nuisance == 1 and cal.n_nuisance == 0
    p = np.zeros(model.n_params)
    np.testing.assert_allclose(cal.predict(p, np.zeros(0)), 100.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(free.predict(p, np.array([2e-3])), 100.002, rtol=0, atol=1e-9)
    assert cal.jacobian(p, np.zeros(0))[1].shape == (12, 0)


def test_known_setup_matches_any_path_to_the_file_and_refuses_what_it_cannot_mean(tmp_path, monkeypatch):
    from mtcomp.identification.problem import build_measurement_models
    from mtcomp.sim import make_ballbar, write_measurements
    from mtcomp.measurement.files import read_measurements
    model = ErrorModel(load_machine("xfyz"))
    th = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    xyz = np.column_stack([100 * np.cos(th), 100 * np.sin(th), np.zeros_like(th)])
    (tmp_path / "bar").mkdir()
    write_measurements(tmp_path / "bar" / "bb.csv", make_ballbar(xyz, np.zeros(3), np.zeros(3),
                                                                length=np.full(12, 100.0)))
    monkeypatch.chdir(tmp_path)
    data = read_measurements("bar/bb.csv")
    for name in ("bar/bb.csv", "./bar/bb.csv", str(tmp_path / "bar" / "bb.csv"), "bb"):
        (mm,) = build_measurement_models(model, [data], known_setup=[name])
        assert mm.n_nuisance == 0, name
    with pytest.raises(InputError, match="--known-setup nosuch.csv: names none of the data files"):
        build_measurement_models(model, [data], known_setup=["nosuch.csv"])
    laser = make_laser(["X"] * 5, ["EXX"] * 5, np.linspace(-100, 100, 5))
    with pytest.raises(InputError, match="a laser file has no set-up to declare known"):
        build_measurement_models(model, [laser], known_setup=[str(laser.path)])
    # the model remembers it: predict treats the calibrated bar as fitted, with no length offset
    from mtcomp.identification.predict import predict_readings
    res = identify(model, [data], known_setup=["bar/bb.csv"])
    assert res.fitted_model.info["known_setup"] == ["bb"]
    pred = predict_readings(res.fitted_model, data)
    assert pred.setup_known and not any("not part of the fit" in n for n in pred.notes)


def test_points_gradient_is_the_jacobian_transposed_times_the_seed(cafxyz):
    """The fit's gradient-only steps use one reverse sweep per row (PointsModel.gradient); it must
    equal J^T v from the full Jacobian, with a normal-deviation column, blank cells and the set-up
    nuisance, and on a 5-axis model away from zero errors."""
    machine, model = cafxyz
    rng = np.random.default_rng(5)
    n = 40
    lo, hi = machine.travel_bounds()
    q = rng.uniform(lo, hi, (n, machine.n_axes))
    abc = np.zeros((n, 3))
    abc[:, 0], abc[:, 2] = q[:, 3], q[:, 4]
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    dev = rng.normal(size=(n, 3)) * 1e-3
    dev[rng.random((n, 3)) < 0.2] = np.nan
    data = make_points(q[:, :3], abc, tool=rng.choice([0.0, 120.0], n), deviation=dev, normal=normal,
                       normal_deviation=rng.normal(size=n) * 1e-3)
    mm = measurement_model(model, data)
    assert mm.fast_gradient
    p = random_parameters(model, rng, mask=model.base_mask.copy()) * 5.0
    nuis = rng.normal(size=mm.n_nuisance) * 1e-3
    v = rng.normal(size=mm.n_obs)
    J, Jn = mm.jacobian(p, nuis)
    gp, gn = mm.gradient(p, nuis, v)
    np.testing.assert_allclose(gp, J.T @ v, rtol=1e-10, atol=1e-12 * np.abs(J.T @ v).max())
    np.testing.assert_allclose(gn, Jn.T @ v, rtol=1e-12, atol=0)


def test_weak_directions_hand_case():
    """The weak-direction rule on a hand-made normal matrix. Unknowns: y1 (1 um of tip error over
    the travel per unit, data information 100 per um^2: standard error 0.1 um), y2 (1 um per unit)
    and a set-up y3 (no tip error) that the data can hardly tell from y2 (correlation 0.999). With y3
    marginalised y2's information is 1 - 0.999^2 = 0.002 per um^2: standard error 22 um > 1 um, so
    it is weak. It is held only
    while the fit moved it by less than 3 standard errors (66 um)."""
    from types import SimpleNamespace

    from mtcomp.identification.fit import _Problem
    prob = SimpleNamespace(metric=np.diag([1.0, 1.0, 0.0]) * 1e-6)      # mm^2 per unit^2
    AB = np.array([[100.0, 0.0, 0.0], [0.0, 1.0, 0.999], [0.0, 0.999, 1.0]])
    B, scale = np.eye(3), np.ones(3)
    W, Q = _Problem._weak_directions(prob, AB, B, scale, 1.0, np.array([5.0, 10.0, 0.0]))
    assert W.shape == (3, 1)
    np.testing.assert_allclose(np.abs(W[:, 0]), [0.0, 1.0, 0.0], atol=1e-9)   # Q-orthonormal: y2
    W, _ = _Problem._weak_directions(prob, AB, B, scale, 1.0, np.array([5.0, 80.0, 0.0]))
    assert W.shape == (3, 0)                        # 80 um is 3.6 standard errors: the data see it
    W, _ = _Problem._weak_directions(prob, np.diag([100.0, 4.0, 1.0]), B, scale, 1.0,
                                     np.array([5.0, 0.5, 0.0]))
    assert W.shape == (3, 0)                        # y3 independent: standard error 0.5 um, not weak


def test_undetermined_directions_keep_every_machine_only_combination(tmp_path):
    """An X positioning run says nothing of Y's straightness: every free EYY coefficient is a
    direction the data leave open, and the model file must record it (predictions along it have no
    standard error). The null space also holds directions that trade a constant of EXX against the
    laser's zero; its SVD basis mixes both kinds, and testing basis vectors one by one lost most
    machine-only directions."""
    from laser_files import write_x_positioning
    from mtcomp.measurement.files import read_measurements
    machine = load_machine("xfyz")
    path = write_x_positioning(tmp_path / "x.csv", (-100, -50, 0, 50, 100, 150), lambda t, d: 1e-4 * t ** 2,
                               2, 0.3, np.random.default_rng(3))
    fitted = identify(machine, [read_measurements(path)]).fitted_model
    u = fitted.uncertainty
    names = list(u["names"])
    N = np.asarray(u["undetermined"])               # (k, m)
    Q, _ = np.linalg.qr(N) if N.shape[1] else (np.zeros((len(names), 0)), None)
    eyy = [i for i, n in enumerate(names) if n.startswith("EYY")]
    assert eyy, names
    for i in eyy:
        e = np.zeros(len(names))
        e[i] = 1.0
        # the unit direction of the coefficient lies in the recorded span
        np.testing.assert_allclose(np.linalg.norm(Q.T @ e), 1.0, rtol=0, atol=1e-6)
    # and the positioning of X, which the run determines, lies outside it
    exx = [i for i, n in enumerate(names) if n.startswith("EXX")]
    for i in exx:
        e = np.zeros(len(names))
        e[i] = 1.0
        assert np.linalg.norm(Q.T @ e) < 0.99


@pytest.mark.parametrize("how", ["identify", "diagnose"])
def test_a_positioning_run_is_the_positioning_error_not_a_pitch(tmp_path, how):
    """A laser positioning run of Y (an axis carrying the tool on XFYZ) at one tool length reads EYY
    plus the tool length times Y's pitch: the data fix the sum only. The component the file names
    takes it; the angles no file names stay at zero (the minimum norm had made a 2,600 urad pitch out
    of a real stage's positioning run of Y, and the controller tables wrote it). The readings are
    fitted as well either way: the model's reading follows the readings' mean per target."""
    from mtcomp.diagnose import diagnose
    from mtcomp.identification.predict import predict_readings
    from mtcomp.measurement.files import read_measurements
    machine = load_machine("xfyz")
    targets = (-150, -100, -50, 0, 50, 100, 150)
    rng = np.random.default_rng(11)
    from laser_files import write_positioning
    path = write_positioning(tmp_path / "y.csv", "Y", targets, lambda t, d: 2e-4 * t ** 2 + 0.05 * t,
                             3, 0.2, rng)
    data = read_measurements(path)
    fitted = (identify(machine, [data]).fitted_model if how == "identify"
              else diagnose(machine, [data]).model)
    angles = [n for n in fitted.params.names if n[:3] in ("EAY", "EBY", "ECY")]
    assert angles
    assert max(abs(fitted.params[n]) for n in angles) < 1e-9          # rad: none invented
    pred = np.asarray(predict_readings(fitted, data, machine).columns["pred_value_um"], float)
    y = np.asarray(data.value, float) * 1e3                              # mm -> um
    t = data.target
    # mean per target of readings and of the fit, up to the laser's zero
    means = np.array([y[t == s].mean() for s in targets])
    fit = np.array([pred[t == s].mean() for s in targets])
    np.testing.assert_allclose(fit - fit.mean(), means - means.mean(), rtol=0, atol=0.3)
