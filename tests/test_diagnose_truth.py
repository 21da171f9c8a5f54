"""diagnose on the independent machine (tests/truth, which shares no code with mtcomp): seed 000's
set-up, and each rule by which a candidate that fits is still refused (issue 11). Fixed seeds."""
import numpy as np
import pytest

from diagnose_truth import compensated_line_error, region_error_um, run, score
from mtcomp.diagnose import _refusal
from mtcomp.diagnose._candidates import Candidate, _abbe_candidates, generate
from mtcomp.diagnose._diagnose import _apply, _common_block, _linear_target, _parsimony, BIC_MARGIN, cv_threshold
from mtcomp.diagnose._linalg import Design, determined_subspace, solve_normal
from mtcomp.diagnose._stack import build_stack
from mtcomp.identification.fit import identify
from mtcomp.machine import load_machine
from mtcomp.models.basis import with_data_basis
from mtcomp.measurement.files import read_measurements
from mtcomp.measurement.readings import data_positions
from truth import FeedAbbe, PeriodicError
from truth.hidden import SEED000_FEEDS, hidden_case, seed000_case

#: campaigns whose model written was once far worse than identify's model of the same files: the
#: least squares, hundreds of um off where its data are weak (9857, 9078, 9079: identify's fit of
#: the model was judged to fit the data clearly worse), or identify's fit moved along a rotary
#: location error seen only at round-off (7008: 315 um off the truth over the data's region)
WRITTEN_CHECKED = (7008, 9857, 9078, 9079)
#: seed 000's gains of the IRC model over the traditional one at 180, 240, 300 mm/min (um)
PAPER_GAINS_UM = dict(zip(SEED000_FEEDS, (0.81, 1.12, 1.18)))
IRC_SHIFT = -800.0


def _written_as_identify(case, d):
    """diagnose's model written is identify's fit of the model it found (docs/diagnose.md, *The model
    written*): over the region its data reach it is no further from the truth than identify's model
    of the same files (1.25 times, and 1 um)."""
    fit = identify(load_machine(case.topology), [read_measurements(p) for p in case.paths])
    assert d.final["written"]["model"] == "penalised", d.final["written"]
    err, ref = region_error_um(case.machine, d.model), region_error_um(case.machine, fit.fitted_model)
    assert err <= 1.25 * ref + 1.0, (err, ref)


@pytest.fixture(scope="module")
def seed000(tmp_path_factory):
    case = seed000_case(0, tmp_path_factory.mktemp("seed000"), irc_shift_mm_per_m_min=IRC_SHIFT)
    d, _ = run(case)
    base, _ = run(case, max_findings=0)
    return case, d, base


def test_seed000_set_up_names_feed_abbe_on_x_only(seed000):
    case, d, _ = seed000
    assert [(f.effect, f.axis) for f in d.findings] == [("feed_dependent_abbe", "X")]
    assert score(case, d, noise_um=0.2).ratio < 1.1
    f = d.findings[0]
    # the yaw's centre moves along Y, by the truth's shift per m/min of feed
    assert f.params["irc_shift_component"] == "IRC_CX_y_f"
    assert f.params["irc_shift_mm_per_m_min"] == pytest.approx(IRC_SHIFT, rel=0.1)
    text = d.summary()
    # Y and Z stand still in these runs: nothing is tried there, and the report says so
    assert "refused: every extension on Y, Z: the data do not move these axes" in text
    # the centre of the yaw moving along X would have to move 10^8 mm: refused as absurd
    assert "further than the machine is large" in text


def test_seed000_extended_model_compensates_the_abbe_line_better(seed000):
    """At 180 and 300 mm/min the extended model's compensated 210 mm line is better than the base
    model's by at least half the paper's gains. At 240 mm/min, the middle of the three feeds, a base
    model fitted to all three feeds already holds the centre where it is at that feed (the centre moves
    in proportion to feed), so there the two must only agree."""
    case, d, base = seed000
    before = compensated_line_error(case, base.model)
    after = compensated_line_error(case, d.model)
    for f in (180.0, 300.0):
        assert before[f] - after[f] >= 0.5 * PAPER_GAINS_UM[f], (f, before, after)
    assert after[240.0] <= before[240.0] + 0.005
    assert max(after.values()) < 0.05                   # the compensated line is straight to 50 nm


@pytest.mark.parametrize("shift", [0.0, IRC_SHIFT])
def test_seed000_set_up_with_the_papers_velocity_sensors(tmp_path, shift):
    """The paper's two-point velocities beside the laser runs: velocities are the derivative of the
    table's motion, its positioning and straightness slopes included (the truth's are not zero), so a
    clean machine gives no finding (the velocity model had left the translation's slope, ten times the
    velocity noise, to be read as structure with feed) and the moving centre is named as before."""
    case = seed000_case(3, tmp_path, irc_shift_mm_per_m_min=shift, velocity_noise_mm_min=1e-4)
    d, _ = run(case)
    if shift == 0.0:
        assert d.verdict == "none" and not d.findings, d.summary()
    else:
        assert [(f.effect, f.axis) for f in d.findings] == [("feed_dependent_abbe", "X")], d.summary()
        assert d.findings[0].params["irc_shift_mm_per_m_min"] == pytest.approx(shift, rel=0.1)


@pytest.fixture(scope="module")
def stack000(tmp_path_factory):
    case = seed000_case(1, tmp_path_factory.mktemp("stack000"))
    machine = load_machine("xfyz")
    data = [read_measurements(p) for p in case.paths]
    machine = with_data_basis(machine, data_positions(machine, data), fourier=False)
    st = build_stack(machine, data)
    st.evaluate(np.zeros(st.probe.n_params), np.zeros(len(st.nuisance_names)))
    T = determined_subspace(_common_block(st))
    for _ in range(2):                      # to the base fit, where candidates' columns are taken
        Ar = _common_block(st) @ T
        phi, _ = solve_normal(Ar.T @ Ar, Ar.T @ _linear_target(st))
        st.evaluate(*_apply(st, T @ phi))
    design = Design(_common_block(st), _linear_target(st), np.ones(len(st)), np.arange(len(st)) % 5, T)
    return st, design


def test_an_axis_the_data_hold_still_gets_no_candidate(stack000):
    st, design = stack000
    assert _refusal.moved_axes(st) == ["X"]
    fit = design.fit(cv=False)
    cands = generate(st, design, np.zeros((len(st), 0)), fit.resid, set())
    assert cands and {c.axis for c in cands} <= {"X", ""}


def test_a_term_acting_where_the_data_do_not_reach_is_refused(stack000):
    st, _ = stack000
    z_terms = [c for c in _abbe_candidates(st, "Z") if np.any(c.columns)]
    assert z_terms                                  # ECZ at z = 0 times the arm does reach the readings
    for c in z_terms:
        assert "the data do not move Z" in _refusal.out_of_reach(st, c)
    x_terms = _abbe_candidates(st, "X")
    assert all(_refusal.out_of_reach(st, c) is None for c in x_terms if np.any(c.columns))


def test_a_term_whose_parameters_the_data_do_not_determine_is_refused(stack000):
    st, design = stack000
    irc = next(c for c in _abbe_candidates(st, "X") if c.params[0] == "IRC_CX_y_f")
    # a second centre shift whose column is the first one's again: one combination only is determined
    twin = Candidate(irc.effect, "X", "twin", np.column_stack([irc.columns[:, 0], 2.0 * irc.columns[:, 0]]),
                     irc.terms, ["IRC_CX_y_f", "IRC_CX_y_f_again"])
    base = design.fit(cv=False)
    dk = design.fit(twin.columns, cv=False).rank - base.rank
    assert dk == 1
    assert "determine only 1 of its 2 parameters" in _refusal.undetermined(twin, dk)
    assert _refusal.undetermined(irc, design.fit(irc.columns, cv=False).rank - base.rank) is None


def test_an_undetermined_offset_of_an_abbe_candidate_is_dropped_not_the_cause(stack000):
    """An Abbe candidate's accompanying feed offset that the data cannot tell from its other columns is
    dropped; the cause stays and is no longer refused (seeds 9172, 9292: the angle-gain candidate was
    refused for an offset along an axis the campaign never read at several feeds)."""
    from mtcomp.diagnose._diagnose import _drop_undetermined_offsets
    from mtcomp.models.terms import FeedOffset
    st, design = stack000
    irc = next(c for c in _abbe_candidates(st, "X") if c.params[0] == "IRC_CX_y_f")
    # an offset whose column is the centre shift's own again: it adds no determined direction
    cand = Candidate(irc.effect, "X", irc.variant, np.column_stack([irc.columns, 3.0 * irc.columns[:, 0]]),
                     irc.terms + [FeedOffset("Z")], irc.params + ["FOFF_Z"], rivals=irc.rivals)
    base = design.fit()
    fit = design.fit(cand.columns)
    assert _refusal.undetermined(cand, fit.rank - base.rank) is not None
    pruned, pfit = _drop_undetermined_offsets(design, np.zeros((len(st), 0)), base, cand, fit)
    assert pruned.params == irc.params
    assert not any(isinstance(t, FeedOffset) and t.axis == "Z" for t in pruned.terms)
    assert _refusal.undetermined(pruned, pfit.rank - base.rank) is None
    np.testing.assert_allclose(pruned.rebuild(st), irc.columns)
    assert pfit.rank == fit.rank and np.isfinite(pfit.cv_sse)
    # a determined offset stays
    kept, _ = _drop_undetermined_offsets(design, np.zeros((len(st), 0)), base, irc, design.fit(irc.columns))
    assert kept is irc


def test_physically_absurd_values_are_refused(stack000):
    st, design = stack000
    irc = next(c for c in _abbe_candidates(st, "X") if c.params[0] == "IRC_CX_y_f")
    size = _refusal.machine_size_mm(st.machine)
    fmax = max(SEED000_FEEDS) / 1000.0
    # a centre moved just inside the machine is possible, just outside it is not
    assert _refusal.absurd(st, irc, [0.9 * size / fmax, 0.0]) is None
    assert "further than the machine is large" in _refusal.absurd(st, irc, [1.1 * size / fmax, 0.0])
    # an angle that grows by more than three times itself over the feeds
    ag = next(c for c in _abbe_candidates(st, "X") if c.params[0] == "AG_CX")
    assert _refusal.absurd(st, ag, [0.1 / fmax]) is None
    assert "would grow by" in _refusal.absurd(st, ag, [1.1 * _refusal.MAX_ANGLE_GAIN / fmax])
    # a backlash larger than the readings it acts on span
    bl = next(c for c in generate(st, design, np.zeros((len(st), 0)), np.zeros(len(st)), set())
              if c.effect == "backlash" and c.variant == "step")
    acts = np.abs(bl.columns[:, 0]) > 0
    span_um = np.ptp(st.y[acts & (st.unit == "um")])
    assert _refusal.absurd(st, bl, [0.5 * span_um * 1e-3]) is None
    assert "more than the" in _refusal.absurd(st, bl, [2.0 * span_um * 1e-3])


def test_thermal_diagnose_prints_its_table_once(tmp_path, capsys):
    """The drift table is the summary's; progress lines (stderr) only name the chosen model."""
    from mtcomp.cli import main
    from truth import TruthMachine, random_effect
    from truth import campaigns as tc
    rng = np.random.default_rng(8)
    effect = random_effect("thermal_drift", TruthMachine("xfyz"), rng, driver="time")
    m = TruthMachine.random("xfyz", rng, effects=[effect], error_motions=False)
    path = tc.thermal(m, tmp_path / "thermal.csv", rng, duration_h=2.0).path
    assert main(["diagnose", "xfyz", str(path), "--json", str(tmp_path / "r.json")]) == 0
    out, err = capsys.readouterr()
    assert (out + err).count("channel   max drift um") == 1
    assert "drift models compared forward in time" in err


def test_rivals_are_told_apart_only_when_both_selection_tests_agree():
    """Hand case of the rivals' rule: the Abbe term (3 parameters) against the feed offset it contains
    (1 parameter) is named when it gains more than cv_threshold(2) noise variances held out and lowers
    the BIC by BIC_MARGIN; when either test leans to the offset, the offset is named; when both lean
    to the Abbe term and only one decisively, the offset is kept and the Abbe term comes back as the
    rival the data do not tell apart."""
    def scored(effect, params, dk, gain, bic):
        c = Candidate(effect, "Z", "", np.zeros((1, dk)), [], params, rivals="feed:Z")
        return (c, None, dk, gain, bic, True)
    need = cv_threshold(2)
    offset = scored("feed_dependent_offset", ["FOFF_Z"], 1, 100.0, -80.0)
    for gain, bic, pick, split in (
            (need + 0.5, -80.0 - BIC_MARGIN - 0.1, "abbe", False),     # both decisive
            (need - 0.5, -80.0 - BIC_MARGIN + 0.1, "offset", False),   # neither
            (need + 30.0, -80.0 - 0.5, "offset", True),                # held out decisive, BIC leans
            (0.5, -80.0 - 60.0, "offset", True),                       # BIC decisive, held out leans
            (need + 30.0, -80.0 + 0.5, "offset", False),               # held out decisive, BIC against
            (-0.5, -80.0 - 60.0, "offset", False)):                    # BIC decisive, held out against
        abbe = scored("feed_dependent_abbe", ["IRC_BZ_x_f", "FOFF_X", "FOFF_Z"], 3, 100.0 + gain, bic)
        got, rival = _parsimony(abbe, [offset, abbe])
        assert got[0] is (abbe if pick == "abbe" else offset)[0], (gain, bic)
        assert (rival is abbe) if split else (rival is None), (gain, bic)
    # several simpler rivals, in either order: the simplest is kept, the Abbe term is the rival alike
    lag = scored("feed_dependent_offset", ["FOFF_Z"], 1, 100.0, -80.0)
    lag[0].info["complexity"] = 1                                  # a direction lag, after the offset
    abbe = scored("feed_dependent_abbe", ["IRC_BZ_x_f", "FOFF_X", "FOFF_Z"], 3, 100.0 + need + 30.0, -85.0)
    for order in ([offset, lag, abbe], [lag, offset, abbe]):
        got, rival = _parsimony(abbe, order)
        assert got is offset and rival is abbe
    # variants of one effect on one axis share a name: no rival to report
    other = scored("feed_dependent_abbe", ["IRC_CZ_y_f"], 1, 100.0, -80.0)
    got, rival = _parsimony(abbe, [other, abbe])
    assert got is other and rival is None


@pytest.mark.parametrize("seed,effect,kind,topology", [
    # a moving centre times a pitch of Z that no run measures: what reaches the readings is mostly a
    # uniform offset growing with feed, plus a profile only the Abbe term follows (14 noise variances
    # held out, more than the 6.7 asked; BIC 5.8 lower, not 10): named a feed offset before
    (9180, "feed_dependent_abbe", "mixture", "cafxyz"),
    # a feed offset whose Abbe rival gains 7.0 noise variances held out by chance, with a BIC 2.7 lower:
    # a BIC margin of 0 between rivals (which names 9180 right) named it an Abbe effect
    (9857, "feed_dependent_offset", "mixture", "cafxyz"),
])
def test_rivals_the_data_do_not_tell_apart_are_not_named(seed, effect, kind, topology, tmp_path):
    case = hidden_case(seed, effect, kind, topology, tmp_path)
    d, _ = run(case)
    sc = score(case, d)
    assert not sc.wrong and d.verdict == "unexplained", [(f.effect, f.axis) for f in d.findings]
    [f] = d.findings
    assert f.effect == "unexplained" and f.axis == "Z"
    assert f.params["explained_alike_by"] == ["feed_dependent_offset Z", "feed_dependent_abbe Z"]
    assert f.params["correlates_with"] == ["feed"] and f.params["where"].startswith("Z, with feed")
    assert f.params["runs"] == [] and f.params["p_value"] is None
    # the model holds the simpler term: the residual is down to the noise, nothing else took it
    assert [t.kind for t in d.model.model.terms] == ["feed_dependent_offset"]
    assert sc.ratio < 1.2
    assert any("only one test is decisive" in r["reason"] for r in d.rejected)
    if seed in WRITTEN_CHECKED:
        _written_as_identify(case, d)


@pytest.mark.parametrize("seed,effect,kind,topology,hidden", [
    # laser runs of Z and ball-bar circles on a 5-axis machine whose rotary axes stay at 0: the rotary
    # location errors reach the readings only through round-off; taken for information they sent the
    # base fit to 1e10 and every reading 50,000 times the noise away
    (7008, "backlash", "mixture", "cafxyz", None),
    # rotary laser runs of C and B: the truth's angular positioning has harmonics up to 5, which the
    # base model follows only with the Fourier order the data allow (it stayed at the machine's 2)
    (7017, "rotary_backlash", "rotary_laser", "cbfxyz", None),
    # a 5 mm screw period seen by a fine run over 240 mm of an 800 mm travel
    (31, "periodic_error", "laser", "xfyz", PeriodicError("X", 5.0, 2.5, 1.0)),
    # a 32 mm period over a 600 mm travel: the periodic candidate's rival (a finer profile whose knots
    # are too far apart to follow the line) does not take it, so the sine earns its place beyond it
    (7018, "periodic_error", "laser", "cbfxyz", None),
    # a 32 mm period of Z, a little longer than the base's knot spacing (28 mm): a rival on twice the
    # base's functions followed it and refused it; the rival's knots are now 32 / 1.5 mm apart
    (9152, "periodic_error", "mixture", "xfyz", None),
    # a 32 mm period of X whose fine run asks for the base's finest knots (16 mm): the rival on twice
    # the base's intervals (8 mm) followed the sine, finer than any base may be; it is capped at 16 mm
    (9650, "periodic_error", "rich", "xfyz", None),
    # an angle of X that grows with feed, read at several feeds, beside positioning runs: the candidate
    # was refused because its offset along an axis read at one feed was not determined (now dropped)
    (9172, "feed_dependent_abbe", "mixture", "xfyz", None),
    # a settling drift in time seen by a thermal file and by laser runs of X taken meanwhile: checked
    # forward in time it lost to the model without it, because the early runs of X could not predict
    # the set-ups of the later files (now only the drift's law is predicted forward)
    (9093, "thermal_drift", "laser", "cbfxyz", None),
    # the same drift in a rich campaign, whose points files take a rotation as their set-up: only
    # future readings that repeat a past one are scored (the residual of a base fitted to all data
    # with the drift left out had taken part of the drift into geometry and set-ups)
    (9305, "thermal_drift", "rich", "xfyz", None),
    # a local defect inside the fine run of X, with the machine's own profiles finer than the default
    # base elsewhere: one window explains what finer bases would gain on that line, so it stays
    (9078, "local_defect", "rich", "xfyz", None),
])
def test_hidden_effect_on_the_independent_machine(seed, effect, kind, topology, hidden, tmp_path):
    case = hidden_case(seed, effect, kind, topology, tmp_path, hidden=hidden)
    d, _ = run(case)
    sc = score(case, d)
    assert sc.right and not sc.wrong, [(f.effect, f.axis) for f in d.findings]
    assert d.verdict == ("unexplained" if effect == "local_defect" else "explained")
    # a defect stays in the residual (it is reported, not modelled): a looser bound there
    assert sc.ratio < (1.2 if effect != "local_defect" else 1.6)
    if seed in WRITTEN_CHECKED:
        _written_as_identify(case, d)


@pytest.mark.parametrize("seed,kind,topology,axis", [
    # the truth's profiles of Y are finer than 16 functions follow over 540 mm: the fine run's held-out
    # runs ask for 24, and nothing is left (it ended 'unexplained Y' with 16)
    (9015, "laser", "cafxyz", "Y"),
    # the same on Y and Z of a rich campaign (ended 'unexplained Y')
    (9181, "rich", "xfyz", "Y"),
    # the pitch of Z (EBZ) read at 21 targets is finer than the positioning lines ask for: the
    # diagnosis's own check, component by component, refines Z (it ended 'unexplained Z')
    (20089, "laser", "xfyz", "Z"),
    # the yaw of Y (ECY) seen by laser and ball-bar circles together (ended 'unexplained Y')
    (20043, "mixture", "cafxyz", "Y"),
    # ball-bar circles at two feeds share 12 poses: their 12 dof gave a noise floor a third low, and
    # the held-out rms looked 1.5 times the noise (now the floor comes from successive differences)
    (20036, "ballbar", "xfyz", None),
    # structure along Y on the ball-bar's YZ circle, where Z turns: it is Z's. The truth's Z
    # profiles are finer than 16 functions follow over the ram's span (-230 .. 170 mm, where it stood
    # with the points' 100 and 160 mm styli): off by 0.68 um (EYZ) and 0.63 urad (EAZ), twice the
    # noise, where Y's straightness EZY is off by 0.03 um. Z's pitch on finer knots gains 274 noise
    # variances held out; Y's EZY on finer knots follows part of it along the circle (174), and was
    # refined instead while the structure's own axis was taken first when it earned its parameters
    (9079, "rich", "xfyz", "Z"),
])
def test_clean_campaign_finer_than_the_default_base_raises_no_alarm(seed, kind, topology, axis, tmp_path):
    case = hidden_case(seed, "", kind, topology, tmp_path)
    d, _ = run(case)
    assert d.findings == [] and d.verdict == "none"
    assert score(case, d).ratio < 1.1
    if axis:
        ax = d.model.model.machine.axis(axis)
        assert ax.spline_intervals + ax.degree > 16          # the base's functions along the axis
    if seed in WRITTEN_CHECKED:
        _written_as_identify(case, d)


def test_a_profile_finer_than_the_default_base_is_no_periodic_error(tmp_path):
    """Seed 7016's laser runs (backlash of Y hidden): the truth's positioning profile of Y (a real
    ISO 230-2 shape interpolated through its targets) wiggles faster than the base's 16 spline
    functions follow. That line was once named a periodic error of Y; then refused (it does not
    replicate along the travel, and a finer profile explains it) and left 'unexplained'. Now the
    fine run's lines are taken one approach direction at a time, the backlash no longer counts as
    noise of the repeats, the base follows the profile, and backlash alone explains the data."""
    case = hidden_case(7016, "backlash", "laser", "cbfxyz", tmp_path)
    d, _ = run(case)
    sc = score(case, d)
    assert sc.right and not sc.wrong, [(f.effect, f.axis) for f in d.findings]
    assert [(f.effect, f.axis) for f in d.findings] == [("backlash", "Y")]
    assert d.verdict == "explained" and sc.ratio < 1.1
    y = d.model.model.machine.axis("Y")
    assert y.spline_intervals + y.degree > 16


def test_feed_abbe_whose_angle_grows_and_whose_centre_moves_is_one_finding(tmp_path):
    """The truth's yaw of X grows with feed (by 23 % per m/min, its constant part too) about a centre
    that moves 41 mm per m/min along Y, which shifts the roll's centre as well; points are read at
    feeds up to 5 m/min, so the effect reaches every file. One finding on X carries it: the angle's
    gain with its constant part (AF_CX) and the moving centre of both angles. Before, the constant
    part and the roll's centre were named as feed-dependent Abbe errors of Y and Z."""
    eff = FeedAbbe("X", angles="C", angle_gain_per_m_min=0.23, irc_shift_mm_per_m_min=(0.0, 41.0, 0.0))
    case = hidden_case(2, "feed_dependent_abbe", "rich", "xfyz", tmp_path, hidden=eff)
    d, _ = run(case)
    sc = score(case, d)
    assert sc.right and not sc.wrong, [(f.effect, f.axis) for f in d.findings]
    f = next(f for f in d.findings if f.effect == "feed_dependent_abbe")
    assert f.params["angle_gains_per_m_min"]["AG_CX"] == pytest.approx(0.23, rel=0.2)
    assert "AF_CX" in f.candidate.params
    assert f.params["irc_shifts_mm_per_m_min"]["IRC_CX_y_f"] == pytest.approx(41.0, rel=0.2)
