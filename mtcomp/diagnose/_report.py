"""Words and numbers of the diagnosis report: the params and the one-sentence evidence of each finding
(something a metrologist can check on the data), and the printed summary."""
from __future__ import annotations

import numpy as np
from scipy.stats import f as f_dist

from ..models.basis import axis_spline
from ..models.terms import motion_pair
from . import _analysis as an
from ._headline import others_text, part_values, set_headline
from ._linalg import rms


def _fmt(v, nd=3):
    return f"{v:.{nd}g}"


def _rival_text(c, rivals, after_fit, before_fit):
    """How the best rival (same residual, other explanation) did on held-out data."""
    if not rivals:
        return ""
    gain_c = before_fit.cv_sse - after_fit.cv_sse
    best = max(rivals, key=lambda s: s[3])
    rc = best[0]
    name = f"{rc.effect.replace('_', ' ')} ({rc.variant})"
    return (f"; the rival explanation {name} gains {best[3] / max(gain_c, 1e-12) * 100:.0f} % as much "
            "held-out")


def _backlash(st, c, theta, resid, rt):
    """(params, evidence) of a reversal step (linear or rotary axis), constant or varying along the axis."""
    a = c.axis
    rotary = c.effect == "rotary_backlash"
    scale, unit = (1e6, "urad") if rotary else (1e3, "um")
    mag = float(theta[0] * scale)
    stp = an.step_test(st, resid, a)
    params = {f"magnitude_{unit}": round(mag, 4)}
    if stp is not None:
        # residuals are in um (or urad for angular readings); the step of the positioning error
        params["step_at_matched_positions"] = round(stp.step, 4)
        ev = (f"At {stp.n_pairs} matched positions of {a}, readings approached in + minus those "
              f"approached in - differ by {stp.step:.3g} {unit} of {a}'s positioning on average (each "
              f"difference over the share of {a}'s positioning its reading sees; standard error "
              f"{stp.se:.2g}); the base model has no direction dependence")
    else:
        ev = f"Readings of {a} split by approach direction with a step of {mag:.3g} {unit}"
    if c.variant == "profile":
        ax = st.machine.axis(a)
        s_grid = np.linspace(*ax.spline_range, 101) if ax.spline_range else np.linspace(*ax.travel, 101)
        phis = np.array(axis_spline(ax).functions(s_grid, False))
        prof = (theta[0] + theta[1:] @ phis) * scale
        params.update({f"reversal_min_{unit}": round(float(prof.min()), 4),
                       f"reversal_max_{unit}": round(float(prof.max()), 4)})
        ev += (f"; the reversal varies along {a} from {prof.min():.3g} to {prof.max():.3g} {unit}"
               f" (held-out data prefer this profile to a constant step)")
    return params, ev


def _periodic_error(st, c, theta, resid, rt):
    """(params, evidence) of a periodic error of a linear axis."""
    a = c.axis
    amp = float(np.hypot(theta[0], theta[1]) * 1e3)
    ln = c.info["line"]
    params = {"period_mm": round(c.info["period_mm"], 5), "amplitude_um": round(amp, 4),
              "phase_deg": round(float(np.degrees(np.arctan2(theta[1], theta[0]))), 2)}
    ev = (f"The {a} residual against {a} position has a Lomb-Scargle line at {ln.period:.4g} mm "
          f"(refined to {c.info['period_mm']:.4g} mm; power {ln.power:.2f}, false-alarm probability "
          f"{ln.fap:.1e}) with {c.info['parts']}")
    return params, ev


def _feed_dependent_offset(st, c, theta, resid, rt):
    """(params, evidence) of a positioning offset proportional to feed."""
    a = c.axis
    v = float(theta[0] * 1e3)
    params = {"um_per_m_min": round(v, 4), "follows_direction": c.variant == "lag"}
    ev = (f"The {a} positioning residual changes by {v:.3g} um per m/min of feed, the same all along "
          f"the axis{' and with the sign of the approach direction' if c.variant == 'lag' else ''}"
          f"{rt}")
    return params, ev


def _feed_dependent_abbe(st, c, theta, resid, rt):
    """(params, evidence) of an angular error that changes with feed, read through its Abbe arm."""
    a = c.axis
    params = {"axis": a}
    # name the part that acts most on the readings (size of its contribution), with its value
    contrib = np.sqrt(np.mean((c.columns * theta) ** 2, axis=0))
    for prefix, what, unit, nd in (("IRC_", "irc_shift", "_mm", 4), ("AG_", "angle_gain", "", 6)):
        idx = [i for i, n in enumerate(c.params) if n.startswith(prefix)]
        if not idx:
            continue
        big = max(idx, key=lambda i: contrib[i])
        params[f"{what}{unit}_per_m_min"] = round(float(theta[big]), nd)
        params[f"{what}_component"] = c.params[big]
        params[f"{what}s{unit}_per_m_min"] = {c.params[i]: round(float(theta[i]), nd) for i in idx}
    parts = []
    for n in [n for n in c.params if n.startswith(("IRC_", "AG_"))]:
        comp = "E" + n.split("_")[1]
        parts.append(f"the rotation centre of {comp} moves along {n.split('_')[2].upper()} with feed"
                     if n.startswith("IRC_") else f"{comp} grows with feed")
    what = " and ".join(parts)
    const = [i for i, n in enumerate(c.params) if n.startswith("AF_")]
    if const:
        # the angle's constant part times its gain (the base model holds no constant angle)
        params["constant_angle_urad_per_m_min"] = {"E" + c.params[i][3:]: round(float(theta[i] * 1e6), 4)
                                                   for i in const}
        what += ", with " + " and ".join(
            f"{v:.3g} urad per m/min of {n} uniform along the axis"
            for n, v in params["constant_angle_urad_per_m_min"].items()) + \
            " from the angle's constant part"
    off = [i for i, n in enumerate(c.params) if n.startswith("FOFF_")]
    if off:
        # the moving centre times the angular error's constant part (not in the base model)
        params["uniform_um_per_m_min"] = {c.params[i][5:]: round(float(theta[i] * 1e3), 4) for i in off}
        what += ", with a uniform " + " and ".join(
            f"{v:.3g} um per m/min along {d}" for d, v in params["uniform_um_per_m_min"].items()) + \
            " from the angular error's constant part"
    ev = (f"The feed-dependent part of the {a} residual follows the fitted angular error profile of "
          f"{a} times the Abbe arm ({what}; Yang et al. 2020){rt}")
    set_headline(params, a, part_values(c.params, theta), contribution=dict(zip(c.params, contrib)))
    return params, ev


def _rotary_pdge(st, c, theta, resid, rt):
    """(params, evidence) of a rotary axis's error motion beyond its location errors."""
    a = c.axis
    comp = c.info["component"]
    unit, scale = ("urad", 1e6) if comp[1] in "ABC" else ("um", 1e3)
    harm = theta.reshape(-1, 2) * scale
    amps = np.hypot(harm[:, 0], harm[:, 1])
    orders = [int(n.rsplit("_", 1)[1][1:]) for n in c.params[::2]]
    span = f"{orders[0]}-{orders[-1]}" if len(orders) > 1 else f"{orders[0]}"
    params = {"component": comp, "harmonics": orders,
              f"harmonic_amplitudes_{unit}": [round(float(x), 4) for x in amps]}
    pair = motion_pair(comp) if 1 in orders else None
    with_pair = (f" (harmonic 1 as the motion turning against the axis, which moves {pair[0]} as much; "
                 f"the one turning with it is the axis's location)") if pair else ""
    ev = (f"The residual varies with the {a} angle at harmonics {span} beyond the location "
          f"errors of {a}; as the error motion {comp}{with_pair} they reach {amps.max():.3g} {unit}")
    return params, ev


def _thermal_drift(st, c, theta, resid, rt):
    """(params, evidence) of a drift in time, temperature or spindle history."""
    driver = c.info["driver"]
    feats = c.info["features"]
    params = {"driver": driver, "features": feats}
    if "tau_s" in c.info:
        params["time_constant_s"] = c.info["tau_s"]
    if "temperatures" in c.info:
        params["temperatures"] = c.info["temperatures"]
    drift = c.columns @ theta
    ranges = {}
    for d in list("XYZ") + sorted(st.hc):
        drift_d = np.zeros(len(st))
        for i, nm in enumerate(c.params):
            f = next((f for f in feats if nm == f"TD_{d}_{f}"), None)
            if f is not None:
                drift_d = drift_d + st.feature(f) * theta[i]
        if np.any(drift_d):
            ranges[d] = float(np.ptp(drift_d) * 1e3)
    if ranges:
        top = max(ranges, key=ranges.get)
        params["direction" if top in ("X", "Y", "Z") else "channel"] = top
        if any(d in ("X", "Y", "Z") for d in ranges):
            params["directions"] = [d for d in ranges if d in ("X", "Y", "Z")]
        params["drift_range_by_direction_um"] = {d: round(v, 4) for d, v in ranges.items()}
    params["drift_range_um"] = round(float(np.ptp(drift[st.unit == "um"])) if np.any(st.unit == "um")
                                     else float(np.ptp(drift)), 4)
    sel = np.isfinite(st.t)
    r = np.corrcoef(drift[sel], resid[sel])[0, 1] if np.std(drift[sel]) > 0 else 0.0
    by = {"time": "time since the start" + (f" (settling with a {c.info['tau_s'] / 3600:.3g} h time "
                                              "constant)" if "tau_s" in c.info else ""),
          "spindle": "the spindle's speed history",
          "temperature": "the temperature(s) " + ", ".join(c.info.get("temperatures", []))}[driver]
    ev = (f"The residual drifts with {by} (correlation {r:.2f} with the fitted drift, range "
          f"{params['drift_range_um']:.3g} um){rt}")
    return params, ev


#: effect -> its params and evidence: function(stack, candidate, theta (internal units), residual
#: before the candidate, rival sentence) -> (params in file units, evidence sentence)
_EFFECT_REPORTS = {"backlash": _backlash, "rotary_backlash": _backlash, "periodic_error": _periodic_error,
                   "feed_dependent_offset": _feed_dependent_offset, "feed_dependent_abbe": _feed_dependent_abbe,
                   "rotary_pdge": _rotary_pdge, "thermal_drift": _thermal_drift}


def evidence_and_params(st, c, theta, before_fit, after_fit, rivals, noise):
    """(params dict in file units, evidence sentence) of a chosen candidate ``c`` with coefficients
    ``theta`` (internal units), given the fits before and after adding it; ({}, "") for an effect
    with no words of its own."""
    rt = _rival_text(c, rivals, after_fit, before_fit)
    report = _EFFECT_REPORTS.get(c.effect)
    return report(st, c, theta, before_fit.resid, rt) if report is not None else ({}, "")


def _runs(st, sel) -> np.ndarray:
    """The run numbers of the rows ``sel`` (rows without a run, -1, left out)."""
    r = st.run[sel]
    return np.unique(r[r >= 0])


def unexplained_params(st, fit, structure, excess, beyond, noise_main, spread, judged=None):
    """(params {'where', 'correlates_with', ...}, evidence, axis) of remaining structure.
    ``excess``: the held-out rms in noise floors; ``beyond``: in what a right model's held-out
    prediction leaves; ``spread``: (n,), how much larger than the noise a right model's held-out
    residual is expected to be, reading by reading;
    ``judged``: (n,) bool, the readings whose held-out residual the excess was judged on (None: all)."""
    if structure:
        s = structure[0]
        sel = st.series == s.series
        span = f"{s.lo:.4g} to {s.hi:.4g}" if s.hi > s.lo else f"{s.lo:.4g}"
        where = f"{s.series}: {s.variable} {span} {s.unit}".rstrip()
        if s.n_departing > 1:
            where += f" (most; {s.n_departing} of {s.dof} bins depart from zero)"
        axis = s.variable.split()[0] if s.variable.endswith("position") else \
            (st.moving[sel][0] if st.moving[sel].size and st.moving[sel][0] else "")
        runs = _runs(st, sel)
        cors = [f"{n} (r = {r:.2f})" for n, r in an.correlations(st, fit.resid, sel)[:3] if abs(r) > 0.2]
        corr = [s.variable] + [x for x in cors if not x.startswith(s.variable)]
        ev = (f"Binned means of the final residual of {s.series} against {s.variable} depart from zero "
              f"(chi-square {s.chi2:.0f} on {s.dof} bins, corrected p = {s.p:.1e}; largest bin mean "
              f"{s.peak:.3g} {st.unit[sel][0]}); no candidate effect explains it")
        params = {"where": where, "correlates_with": corr, "runs": [int(r) for r in runs],
                  "p_value": float(s.p)}
        return params, ev, axis
    where = "all data"
    cors = [(n, r) for n, r in an.correlations(st, fit.resid, np.ones(len(st), dtype=bool)) if abs(r) > 0.2]
    corr = [f"{n} (r = {r:.2f})" for n, r in cors[:3]] or ["nothing measured"]
    # the axis of the strongest correlate, when it is an axis's approach direction or position
    axis = ""
    if cors:
        words = cors[0][0].split()
        if cors[0][0].startswith("approach direction of "):
            axis = words[-1]
        elif cors[0][0].endswith(" position"):
            axis = words[0]
    # p: the held-out mean square over the noise variance, against what a right model leaves (the
    # noise times each reading's held-out spread); the noise is itself estimated (its dof): an F test
    z = fit.cv_resid / noise_main.sigma / spread
    sel = np.isfinite(z) & (st.unit == noise_main.unit) & (True if judged is None else judged)
    p = (float(f_dist.sf(np.mean(z[sel] ** 2), int(sel.sum()), max(noise_main.dof, 1)))
         if sel.any() else None)
    runs = _runs(st, np.ones(len(st), dtype=bool))
    left = 0 if judged is None else int(np.sum(~judged))
    ev = (f"The held-out residual stays {excess:.2f} times the noise floor ({noise_main.sigma:.3g} "
          f"{noise_main.unit})"
          + (f", {beyond:.2f} times what a right model's held-out prediction leaves (the other folds "
             f"fix some readings' prediction only loosely)" if abs(beyond - excess) > 0.005 else "")
          + " with no localised structure"
          + (f" ({left} reading(s) whose prediction only their own fold determines left out)" if left else "")
          + "; no candidate effect explains it")
    return ({"where": where, "correlates_with": corr, "runs": [int(r) for r in runs], "p_value": p},
            ev, axis)


def _other_units(fit: dict) -> str:
    """'; angular rms .. urad, held-out .. urad' and the same for velocities, where the data hold them."""
    return "".join(f"; {what} rms {_num(fit.get('rms_' + key))} {unit}, held-out "
                   f"{_num(fit.get('heldout_rms_' + key))} {unit}"
                   for what, key, unit in (("angular", "urad", "urad"), ("velocity", "um_min", "um/min"))
                   if f"rms_{key}" in fit)


def summary(diag, details=()) -> str:
    """Human-readable report; ``details`` (lines) go before the verdict."""
    lines = []
    nz = [f"{n.sigma:.3g} {u} ({n.source}{', %d repeat groups' % n.n_groups if n.source == 'repeats' else ''})"
          + "".join(f", {name} {sigma:.3g} {u} (its own)" for name, sigma in n.by_series.items())
          for u, n in diag.noise.items()]
    lines.append(f"observations: {diag.n_obs}; noise floor: {'; '.join(nz)}")
    lines.append(f"held-out evaluation: {diag.folds}")
    for o in diag.outliers:
        lines.append(f"left out as an outlier: {o}")
    b = diag.base
    lines.append(f"base model ({b['n_params']} parameters, {b['n_determined']} determined by the data): "
                 f"rms {_num(b.get('rms_um'))} um, held-out {_num(b.get('heldout_rms_um'))} um"
                 + _other_units(b))
    if b.get("refined"):
        lines.append("base refined by the diagnosis (its held-out data asked for a finer spline along "
                     "these axes): " + ", ".join(f"{a} {k} spline functions" for a, k in b["refined"].items()))
    if not diag.findings:
        lines.append("findings: none")
    for i, f in enumerate(diag.findings, 1):
        ps = ", ".join(f"{k}={_short(v)}" for k, v in f.params.items()
                       if not isinstance(v, dict) or k in _PRINTED_DICTS)
        if "headline" in f.params:           # a finding of several parts: the one that stands out
            ps = f.params["headline"] + others_text(f.params)
        lines.append(f"{i}. {f.effect}{' on ' + _on(f) if _on(f) else ''}: {ps}")
        lines.append(f"   evidence: {f.evidence}")
        if f.effect != "unexplained" or f.candidate is not None:     # a term the model holds
            lines.append(f"   held-out rms {f.heldout_rms_before:.4g} -> {f.heldout_rms_after:.4g} {f.unit}")
    for r in diag.rejected:
        variant = f" ({r['variant']})" if r.get("variant") else ""
        on = f" on {r['axis']}" if r.get("axis") else ""
        lines.append(f"refused: {r['effect']}{on}{variant}: {r['reason']}")
    from ._untested import untested_lines
    lines += untested_lines(getattr(diag, "untested", None) or {})
    fz = diag.final
    rank = getattr(diag, "rank", None)
    dof = (f", {rank} of them determined by the data, {diag.n_obs - rank} degrees of freedom left"
           if rank is not None else "")
    lines.append(f"final model ({fz['n_params']} parameters{dof}): rms {_num(fz.get('rms_um'))} um, "
                 f"held-out {_num(fz.get('heldout_rms_um'))} um"
                 + _other_units(fz))
    written = fz.get("written")
    if written:
        weak = (f"its data fix {written['weak']} combination(s) of the least squares only weakly, to "
                f"{written['largest_sd_um']:.3g} um of tool-tip error at worst; " if written["weak"] else "")
        from ._open import worse_files
        worse = (f"; it fits the data clearly worse than the least squares (residual "
                 f"{_num(written.get('residual_sd'))} against {_num(written.get('residual_sd_least_squares'))}"
                 f" noise floors{worse_files(written)}): structure the model lacks" if written.get("fits_worse")
                 else "")
        worse += "; Gauss-Newton did not converge within its iterations" if written.get("converged") is False else ""
        held = (f", held-out {_num(written['heldout_rms_um'])} um" if written.get("heldout_rms_um") is not None
                else "")
        lines.append(f"model written: the final model fitted as identify fits it ({weak}its profiles follow "
                     f"the smoothest curve where the data are silent, {written['held']} combination(s) the "
                     f"smoothness does not fix either are held where they predict the least error{worse}); "
                     f"rms {_num(written.get('rms_um'))} um{held} (the figures above are the least squares'"
                     + (", which the model written does not reach)" if written.get("fits_worse") else ")"))
        if written.get("sparse"):
            lines.append(f"model written: {written['sparse']}")
    ref = diag.reference.get("linear_regression_all_temperatures")
    if ref:
        lines.append(f"reference: plain linear regression on all {len(ref['temperatures'])} temperatures "
                     f"({ref['n_params']} parameters): rms {_num(ref.get('rms_um'))} um, held-out "
                     f"{_num(ref.get('heldout_rms_um'))} um")
    if diag.thermal is not None:
        lines.append(diag.thermal.summary())
    lines += list(details)
    meaning = VERDICT_MEANING.get(diag.verdict, "")
    if diag.final.get("not_judged") and diag.verdict == "none":
        meaning = "the base model explains the readings it could judge down to the noise"
    if getattr(diag, "untested", None) and diag.verdict in ("none", "explained"):
        meaning += "; it says nothing of what these data could not test (\"not testable\" above)"
    lines.append(f"verdict: {diag.verdict} ({meaning}{_not_judged(diag)})")
    return "\n".join(lines)


#: the finding parameters held as dicts that the summary prints (the others are in REPORT.json)
_PRINTED_DICTS = ("drift_range_by_direction_um",)


def _on(f) -> str:
    """What a finding is on, printed: its axis, or for a drift every tip direction it holds."""
    held = f.params.get("directions") if f.effect == "thermal_drift" else None
    return ", ".join(held) if held else f.axis


def _not_judged(diag) -> str:
    """What the verdict leaves out, beside it: the readings whose held-out prediction rests on what
    only their own fold determines (their residual measures what the other folds cannot see)."""
    nj = diag.final.get("not_judged")
    if not nj:
        return ""
    files = nj.get("files") or {}
    named = f" ({', '.join(f'{k} {v}' for k, v in files.items())})" if files else ""
    text = (f"; judged without {nj['readings']} of the {nj['of']} readings{named}, whose held-out "
            f"prediction rests on what only their own fold determines: their held-out rms "
            f"{_num(nj['heldout_rms'])} {nj['unit']} is in the held-out figures above and says what the "
            "folds cannot check, not that the model fits them")
    if nj.get("times_noise"):
        text += (f". That is {nj['times_noise']:.3g} times the noise: what only these "
                 "readings measure, nothing else checks, and the model may be wrong there unseen (two "
                 "errors they cannot tell apart, e.g. a rotary axis's radial error motion and its "
                 "positioning read at one radius, or a profile's stretch only one part's outermost "
                 "points reach): repeat the test another way (another radius, another set-up or "
                 "instrument, a part that reaches there too) before trusting the model there")
    return text


#: what each verdict says, printed beside it (docs/diagnose.md)
VERDICT_MEANING = {
    "none": "the base model explains the data down to the noise",
    "explained": "the findings above bring the held-out residual down to the noise",
    "unexplained": "structure remains that no candidate explains, or two explain it alike and the "
                   "data cannot say which; see the findings above",
}


def _num(v):
    return "n/a" if v is None else f"{v:.4g}"


def _short(v):
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list):
        return "[" + ", ".join(_short(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {_short(x)}" for k, x in v.items()) + "}"
    return str(v)


__all__ = ["evidence_and_params", "unexplained_params", "summary", "rms"]
