"""What the printed report says of a parameter's uncertainty is what MODEL.json says of it.

* The printed standard error of a squareness or location error comes from the model's covariance,
  as MODEL.json's ``std_error`` does. A covariance of parameters in mm and rad spans 1e6 in its
  variances: decomposed as it stands, a cut relative to its largest eigenvalue dropped every angle's
  variance beside one profile coefficient of 1e4 mm^2 (a double turntable's campaign printed
  "A0B 46.7 +- 0.57 urad" while MODEL.json said 3.43).
* A profile whose shape the data measure has a range with a standard error, whatever the rest of
  the model holds: judged against the model's largest standard error, a laser-measured positioning
  (0.03 um) read "not determined by the data" beside one spline function of 2e7 um.
* A term diagnose adds whose parameter is seen only through another chosen factor (a feed-dependent
  Abbe term's moving rotation centre times the fitted yaw) carries the standard error the
  selection's least squares gives it, when the model written is identify's penalised fit: judged
  where the yaw is zero, that fit left the centre without one (the independent truth machine,
  tests/truth: -838.8 +- 35.8 mm per m/min against the truth's -800)."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp.identification.predict import Undetermined
from mtcomp.identification.report import component_ranges, location_values
from mtcomp.machine import load_machine
from mtcomp.models.chain import ErrorModel
from mtcomp.models.model_file import FittedModel
from mtcomp.models.params import ParameterSet

#: 3.43 urad, as a double turntable's A0B
ANGLE_SD_RAD = 3.43e-6


def _model(variances: dict, values: dict | None = None) -> FittedModel:
    """An xfyz model fitted in the parameters of ``variances`` (name -> variance, internal units),
    uncorrelated, nothing undetermined."""
    machine = load_machine("xfyz")
    model = ErrorModel(machine, [])
    params = ParameterSet(model.param_specs)
    for n, v in (values or {}).items():
        params[n] = v
    names = tuple(variances)
    C = np.diag([variances[n] for n in names])
    se = np.full(len(params), np.nan)
    for n in names:
        se[params.index(n)] = np.sqrt(variances[n])
    params.std_errors = se
    support = {a.name: a.travel for a in machine.linear_axes}
    return FittedModel(model, params, support=support,
                       uncertainty={"names": names, "covariance": C, "undetermined": np.zeros((len(names), 0))})


def test_the_printed_standard_error_is_the_model_file_s():
    # a squareness of 3.43 urad beside one straightness coefficient of 100 mm standard error
    fitted = _model({"EYX_b10": 1e4, "C0Y": ANGLE_SD_RAD ** 2}, {"C0Y": 40e-6})
    written = fitted.to_json_dict()["parameters"]["C0Y"]["std_error"]
    assert written == pytest.approx(3.43, rel=1e-9)
    printed = {v.name: v for v in location_values(fitted)}["C0Y"]
    assert printed.status == "fitted"
    assert printed.sd == pytest.approx(written, rel=1e-6)
    # and a prediction resting on it: J C J^T by hand
    J = np.zeros((1, len(fitted.params)))
    J[0, fitted.params.index("C0Y")] = 2.0e6            # urad of a reading per rad of C0Y
    assert Undetermined.of(fitted).std(J)[0] == pytest.approx(2.0 * 3.43, rel=1e-6)


def test_a_measured_profile_has_a_range_beside_a_huge_coefficient():
    # the positioning of X on its ten coefficients, each to 0.03 um, rising by 0.5 um per
    # coefficient; Z's last positioning coefficient to 2e7 um (a function at the data's edge that
    # no reading holds)
    xs = [f"EXX_b{k}" for k in range(1, 11)]
    fitted = _model({**{n: (0.03e-3) ** 2 for n in xs}, "EZZ_b10": 2e4 ** 2},
                    {n: 1e-5 * (k - 4.5) * 50.0 for k, n in enumerate(xs)})
    ranges, _, _ = component_ranges(fitted)
    exx = next(r for r in ranges if r.axis == "X" and r.component == "EXX")
    assert exx.status == "fitted", exx
    # the range's standard error by hand: the profile's largest minus smallest value is a
    # combination of the coefficients; at most the two end coefficients' (0.03 um each)
    assert 0.0 < exx.sd <= np.sqrt(2.0) * 0.03 + 1e-9
    assert exx.range > 1.0


def test_an_added_rotation_centre_carries_its_standard_error(tmp_path):
    from diagnose_truth import run
    from truth import campaigns as tc
    from truth.hidden import seed000_case
    # seed 000's laser runs of X at three feeds (a yaw turning about a centre that moves -800 mm
    # per m/min along Y) and one ball-bar circle in XY, which leaves combinations weak: the model
    # written is identify's penalised fit
    case = seed000_case(0, tmp_path)
    case.paths.append(tc.ballbar_circles(case.machine, tmp_path / "circle.csv", np.random.default_rng(100),
                                         planes=("XY",), t0_s=1e5).path)
    d, _ = run(case)
    assert d.final["written"]["model"] == "penalised", d.final.get("written")
    m = d.model
    i = m.params.index("IRC_CX_y_f")
    value, sd = m.params.values[i], m.params.std_errors[i]
    assert np.isfinite(sd) and 0.0 < sd < 100.0, sd
    assert abs(value - (-800.0)) <= 3.0 * sd, (value, sd)
    # not among what the data leave open, and in the covariance predictions use
    k = list(m.uncertainty["names"]).index("IRC_CX_y_f")
    assert np.allclose(m.uncertainty["undetermined"][k], 0.0)
    assert m.uncertainty["covariance"][k, k] == pytest.approx(sd ** 2, rel=1e-9)
    # the printed location values are MODEL.json's
    written = m.to_json_dict()["parameters"]
    for v in location_values(m):
        if v.status == "fitted":
            assert v.sd == pytest.approx(written[v.name]["std_error"], rel=1e-6), v
    # REPORT.json quotes it, and the evidence quotes the finding's figures to the digits it prints
    f = d.findings[0]
    assert f.params["irc_shift_sd_mm_per_m_min"] == pytest.approx(sd, abs=1e-4)
    for direction, v in f.params["uniform_um_per_m_min"].items():
        assert f"a uniform {v:.3g} um per m/min along {direction}" in f.evidence, (v, f.evidence)


def test_a_seen_through_factor_s_covariance_with_the_files_set_ups_is_left_out_with_the_rest():
    """A factor whose variance is rewritten from the least squares (seen_through_factor) keeps no
    covariance with the penalised fit's other parameters, nor with its fitted files' set-ups: predict
    puts both in one joint covariance ([J D] C [J D]^T), where a cross term the rewrite left behind
    would pair the least squares' variance with the penalised fit's covariance."""
    from types import SimpleNamespace
    from mtcomp.diagnose._open import seen_through_factor
    from mtcomp.models.params import ParamSpec
    specs = (ParamSpec("a", "um", "X:EXX"), ParamSpec("b", "um", "shift", base=False))
    lsq = SimpleNamespace(params=ParameterSet(specs, std_errors=np.array([0.1, 0.2])))
    setup = {"names": ("f:zero",), "to_file": np.array([1e3]), "cross": np.array([[0.002, 0.0005]]),
             "covariance": np.array([[0.04]])}
    u = {"names": ("a", "b"), "covariance": np.array([[0.01, 3e-4], [3e-4, 1e-6]]),
         "undetermined": np.array([[0.0], [1.0]]), "setup": setup}     # b alone is left open
    penalised = SimpleNamespace(params=ParameterSet(specs, std_errors=np.array([0.1, np.nan])), uncertainty=u)
    params, u = seen_through_factor(lsq, penalised, 2.0)
    # b: the least squares' variance times s2, apart from a and from the set-up; a as it was
    np.testing.assert_allclose(u["covariance"], [[0.01, 0.0], [0.0, 0.08]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(u["setup"]["cross"], [[0.002, 0.0]], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(u["setup"]["covariance"], [[0.04]])
    np.testing.assert_array_equal(setup["cross"], [[0.002, 0.0005]])     # the penalised fit's own: unchanged
    assert u["undetermined"].shape[1] == 0 and params.std_errors[1] == pytest.approx(np.sqrt(0.08), rel=1e-12)
