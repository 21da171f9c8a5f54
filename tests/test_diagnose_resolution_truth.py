"""diagnose's resolution on the independent machine (tests/truth, which shares no code with mtcomp):
rotary error motions of harmonics 2-4, seed 003 through the generic path, a screw period beside a
backlash, a feed-dependent Abbe error whose angular profile is finer than the base's knot floor.
The cases are written in tests/resolution_cases.py; benchmarks/bench_diagnose_resolution.py runs
them on more machines."""
import numpy as np
import pytest

from diagnose_truth import run, score
from resolution_cases import (abbe_fine_case, fine_run_case, pdge_case, pitch_line_case, seed003_diagnosed,
                              x_line_error)


def test_rotary_error_motions_of_harmonics_2_to_4_are_explained(tmp_path):
    """Five error motions of C (radial pair, axial, tilt pair), harmonics 2, 3 and 4, seen by the
    three-sphere set-up: each is named, with the harmonics the data ask for, and the held-out rms is
    within 1.1 times the noise (with harmonics up to 3 only it stayed at 2.3 times, 'unexplained')."""
    case = pdge_case(0, tmp_path, circles=False)
    d, _ = run(case)
    sc = score(case, d)
    assert d.verdict == "explained" and not sc.wrong, d.summary()
    assert sorted(f.params["component"] for f in d.findings) == ["EAC", "EBC", "EXC", "EYC", "EZC"]
    assert sc.ratio <= 1.1
    # the truth has harmonics 2-4: every component's series reaches 4, none stops below it
    assert all(max(f.params["harmonics"]) >= 4 for f in d.findings), [f.params for f in d.findings]


def test_each_harmonic_that_held_out_data_earn_is_kept(tmp_path):
    """Machine 6's C error motions (harmonics 2-4, the three-sphere set-up): the fourth harmonics of
    the tilt pair (2.0 and 1.9 urad in the truth) each lower the held-out sum of squares beyond order
    3 by more than noise could, and no higher order beats order 4: every component's harmonics 2-4
    are within 0.2 um or 0.8 urad of the truth's amplitudes (tests/truth). They were dropped, 1.97
    and 1.88 urad off, while the orders of one series were told apart by the BIC margin too (EAC)
    and against the best order alone (EBC: order 3 against order 5, not against order 4)."""
    case = pdge_case(6, tmp_path, circles=False)
    d, _ = run(case)
    assert d.verdict == "explained", d.summary()
    turn = np.linspace(0.0, 2 * np.pi, 720, endpoint=False)
    truth = case.hidden.profiles()
    assert sorted(f.params["component"] for f in d.findings) == sorted(truth)
    for f in d.findings:
        comp = f.params["component"]
        unit, scale, tol = ("um", 1e3, 0.2) if comp[1] in "XYZ" else ("urad", 1e6, 0.8)
        fitted = dict(zip(f.params["harmonics"], f.params[f"harmonic_amplitudes_{unit}"]))
        true = np.abs(np.fft.rfft(truth[comp](turn))) * 2.0 / turn.size * scale
        for k in (2, 3, 4):
            assert fitted.get(k, 0.0) == pytest.approx(true[k], abs=tol), (comp, k, fitted, true[1:6])


def test_seed003_axis_points_through_diagnose(tmp_path):
    """Seed 003's three-sphere file (C error motions of harmonics 2-5) on the built-in machine, which
    declares no error motions: diagnose finds them, and the C-axis points over the turn are within the
    paper's 0.3 um mean and 0.78 um max. Each point's offset over the turn is removed: X, Y and Z
    stand still at the bar's positions, so their errors there trade with the axis's location (the
    paper compensated them first; identify is told so, diagnose is not)."""
    d, raw, turn = seed003_diagnosed(0, tmp_path)
    assert {f.effect for f in d.findings} == {"rotary_pdge"}, d.summary()
    assert turn.mean() <= 0.3 and turn.max() <= 0.78, (turn.mean(), turn.max())
    # the offset left open is the same at every angle: removing it changes each point by one vector
    assert raw.mean() > turn.mean()


def test_periodic_error_and_backlash_of_one_axis_are_both_named(tmp_path):
    """A 20 mm screw period (1.5 um) beside a 5 um backlash of X, read as a pitch table (every 5 mm,
    three runs both ways): both are named and nothing else."""
    case = pitch_line_case(0, tmp_path)
    d, _ = run(case)
    assert sorted((f.effect, f.axis) for f in d.findings) == [("backlash", "X"), ("periodic_error", "X")]
    assert d.verdict == "explained" and score(case, d).ratio < 1.1
    bl = next(f for f in d.findings if f.effect == "backlash")
    assert bl.params["magnitude_um"] == pytest.approx(5.0, abs=0.3)
    per = next(f for f in d.findings if f.effect == "periodic_error")
    assert per.params["period_mm"] == pytest.approx(20.0, rel=0.01)


def test_a_screw_period_read_by_one_fine_run_among_sparse_targets_is_named(tmp_path):
    """A 25 mm screw period (2 um) beside a 5 um backlash of X, read by ISO 230-2 runs at irregular
    targets about 29 mm apart over the 800 mm travel (the period aliased there) and a fine run every
    2.5 mm over -100..20 mm: both are named, the period where the fine run resolves it, with the
    held-out gain (it was refused: the thirds of all readings by count held sparse targets where the
    sine is not significant, and the base's knots took a share of it that varies along the run)."""
    case = fine_run_case(1, tmp_path)
    d, _ = run(case)
    assert sorted((f.effect, f.axis) for f in d.findings) == [("backlash", "X"), ("periodic_error", "X")], \
        d.summary()
    per = next(f for f in d.findings if f.effect == "periodic_error")
    assert per.params["period_mm"] == pytest.approx(25.0, rel=0.01)
    assert per.params["amplitude_um"] == pytest.approx(2.0, abs=0.2)
    assert "seen over -100..20 mm only" in per.evidence
    assert per.heldout_rms_before - per.heldout_rms_after > 0.5
    assert d.verdict == "explained" and score(case, d).ratio < 1.15


def test_a_bump_inside_the_fine_run_is_not_a_screw_period(tmp_path):
    """The same campaign with a 30 mm wide, 3 um bump inside the fine run in place of the screw
    period: its line is refused (its halves do not agree), and X is left unexplained."""
    case = fine_run_case(0, tmp_path, defect=True, width_mm=30.0)
    d, _ = run(case)
    refused = [r for r in d.rejected if r["effect"] == "periodic_error"]
    assert refused and "does not replicate" in refused[0]["reason"], d.summary()
    assert [(f.effect, f.axis) for f in d.findings] == [("backlash", "X"), ("unexplained", "X")]


def test_the_model_written_follows_the_penalty_between_sparse_targets(tmp_path):
    """The screw-period campaign of another machine: its data leave no combination of the least
    squares weak by identify's rule, and that least squares' profile between the ISO targets (29 mm
    apart on 16 mm knots) was 105 um rms off the truth (760 um peak to peak). The model written is
    identify's penalised fit: between the targets X's error is 2.5 um rms off (13 um peak to peak),
    what is left being the screw period, which the fine run's 120 mm gave as 24.4 mm for 25 mm, so
    that the two drift apart along the travel (the noise is 0.3 um)."""
    case = fine_run_case(2, tmp_path)
    d, _ = run(case)
    e, fine = x_line_error(case, d.model)
    away = e[~fine]
    assert np.sqrt(np.mean(away ** 2)) < 4.0 and np.ptp(away) < 20.0, (np.sqrt(np.mean(away ** 2)), np.ptp(away))
    written = d.final["written"]
    assert written["model"] == "penalised" and written["weak"] == 0, d.summary()


def test_feed_abbe_with_a_yaw_finer_than_the_knot_floor_is_explained(tmp_path):
    """Seed 000's set-up on a machine whose yaw of X carries a 25 mm wave (4 urad): the base's knots
    may come no closer than 16 mm for the positioning error (a screw period is diagnose's to name),
    but the yaw is refined to the data's 5 mm spacing, and the feed-dependent Abbe error is explained
    (it ended 'unexplained' at 4.7 times the noise)."""
    case = abbe_fine_case(0, tmp_path)
    d, _ = run(case)
    assert [(f.effect, f.axis) for f in d.findings] == [("feed_dependent_abbe", "X")], d.summary()
    assert d.verdict == "explained"
    assert score(case, d, noise_um=0.2).ratio < 1.1
    x = d.model.model.machine.axis("X")
    assert (x.spline_range[1] - x.spline_range[0]) / x.spline_intervals < 16.0
    assert np.isfinite(d.final["heldout_rms_um"])
