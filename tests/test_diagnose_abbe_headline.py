"""The headline of a feed-dependent Abbe finding (docs/diagnose.md, ``headline`` keys). A service
engineer's table yaw grew by 5 urad per m/min of feed, uniform along X (their numpy truth); the
model written held it as AF_CX = 4.994 +- 0.036 urad per m/min, beside AG_CX = 0.0057 +- 0.008 (the
yaw's profile scaled by feed, not in the truth) and two offsets. The report headlined
angle_gain_per_m_min = 0.0057, with no standard error, and left the real effect in a side field.
These are MODEL.json's numbers of that diagnosis (file units): the headline must be AF_CX with its
standard error, and AG_CX said to be not significant."""
from __future__ import annotations

import numpy as np

from mtcomp.diagnose._candidates import Candidate
from mtcomp.diagnose._headline import quote_standard_errors as _quote_standard_errors
from mtcomp.diagnose.result import Finding
from mtcomp.models.params import ParameterSet, ParamSpec

#: name -> (unit, value, standard error) as MODEL.json gave them
WRITTEN = {"AG_CX": ("1", 0.005693889, 0.008011259), "AF_CX": ("urad", 4.994408456, 0.035954441),
           "FOFF_X": ("um", -0.000957832, 0.010713651), "FOFF_Y": ("um", 0.000370645, 0.031091590)}


def _finding_and_model():
    names = list(WRITTEN)
    specs = tuple(ParamSpec(n, WRITTEN[n][0], "abbe_irc:X", base=False) for n in names)
    to_file = np.array([s.to_file for s in specs])
    model = type("Written", (), {})()
    model.params = ParameterSet(specs, np.array([WRITTEN[n][1] for n in names]) / to_file,
                                np.array([WRITTEN[n][2] for n in names]) / to_file)
    cand = Candidate("feed_dependent_abbe", "X", "gain+constant:AG_CX", np.zeros((4, 4)), [], names)
    # the params the report gave before the model was written (the fit's, as REPORT.json had them)
    params = {"axis": "X", "angle_gain_per_m_min": 0.005693, "angle_gain_component": "AG_CX",
              "angle_gains_per_m_min": {"AG_CX": 0.005693}, "constant_angle_urad_per_m_min": {"ECX": 4.9942},
              "uniform_um_per_m_min": {"X": -0.001, "Y": 0.0004}}
    return Finding("feed_dependent_abbe", "X", params, "", 1.70, 1.15, candidate=cand), model


def test_the_significant_part_is_the_headline_with_its_standard_error():
    f, model = _finding_and_model()
    _quote_standard_errors([f], model)
    p = f.params
    assert p["headline_component"] == "AF_CX" and p["headline_unit"] == "urad"
    assert abs(p["headline_per_m_min"] - 4.994408) < 1e-6
    assert abs(p["headline_sd_per_m_min"] - 0.035954) < 1e-6
    assert p["headline_significant"] is True
    # 4.994 / 0.036 = 138.9 standard errors from zero, by hand
    assert p["headline"] == ("ECX uniform along X grows by 4.994 +- 0.036 urad per m/min of feed "
                             "(AF_CX, 139 standard errors from zero)")
    assert abs(p["parts_sd_per_m_min"]["AG_CX"] - 0.008011) < 1e-6
    assert abs(p["angle_gain_sd_per_m_min"] - 0.008011) < 1e-6


def test_the_printed_line_leads_with_it_and_calls_the_gain_not_significant():
    from mtcomp.diagnose._headline import others_text
    f, model = _finding_and_model()
    _quote_standard_errors([f], model)
    text = others_text(f.params)
    # 0.0057 < 2 x 0.008: not significant; the offsets neither
    assert "AG_CX 0.005694 +- 0.008 (not significant)" in text
    assert "FOFF_X -0.000958 +- 0.011 um (not significant)" in text
    assert "AF_CX" not in text


def test_a_part_without_a_standard_error_leaves_the_headline_chosen_on_contributions():
    """AG_CX with no standard error in the model written: the parts cannot be ranked in standard
    errors, and their values (a ratio, urad, um) are no measure of which acts most: the headline
    the report chose on contributions stays; the standard errors there are still quoted."""
    f, model = _finding_and_model()
    f.params.update({"headline_component": "AG_CX", "headline": "kept"})
    model.params.std_errors[model.params.index("AG_CX")] = np.nan
    _quote_standard_errors([f], model)
    assert f.params["headline_component"] == "AG_CX" and f.params["headline"] == "kept"
    assert "AG_CX" not in f.params["parts_sd_per_m_min"]
    assert abs(f.params["parts_sd_per_m_min"]["AF_CX"] - 0.035954) < 1e-6
