"""The headline of a feed-dependent Abbe finding (docs/diagnose.md, ``headline`` keys).

One finding may hold several parts: an angle's rotation centre moving with feed (``IRC_``), the
angle's profile scaled by feed (``AG_``), its constant part growing with feed (``AF_``) and the
uniform offsets these make (``FOFF_``). The report named the part of the first two kinds that acts
most, whatever its standard error: a table yaw growing by 5 urad per m/min (``AF_CX`` 4.994 +- 0.036)
was a side field while the headline was ``AG_CX`` = 0.0057, within its standard error of 0.008 of
zero. The headline is the cause part (``IRC_``, ``AG_``, ``AF_``) furthest from zero in standard
errors once the model written gives them (:func:`quote_standard_errors`), and before that, the one
whose contribution to the readings is largest; every part is listed with its value and standard
error.
"""
from __future__ import annotations

import numpy as np

#: a part this many standard errors from zero or more is significant
SIGNIFICANT_SD = 2.0
#: file units per internal unit of each part's parameter, and the unit's name
_FACTORS = {"IRC_": (1.0, "mm"), "AG_": (1.0, ""), "AF_": (1e6, "urad"), "FOFF_": (1e3, "um")}
#: the parts that are a cause (the offsets only come with them)
_CAUSES = ("IRC_", "AG_", "AF_")


def _prefix(name: str) -> str:
    return next(p for p in _FACTORS if name.startswith(p))


def _what(name: str, axis: str) -> str:
    """A part in words: what changes by its value per m/min of feed."""
    if name.startswith("AF_"):
        return f"E{name[3:]} uniform along {axis} grows by"
    if name.startswith("AG_"):
        return f"E{name[3:]}'s profile along {axis} is scaled by 1 plus"
    if name.startswith("IRC_"):
        part = name.split("_")
        return f"the rotation centre of E{part[1]} moves along {part[2].upper()} by"
    return f"a uniform offset along {name[5:]} of"


def _value(v: float, sd: float | None, unit: str) -> str:
    unit = f" {unit}" if unit else ""
    return f"{v:.4g}{unit}" if sd is None or not np.isfinite(sd) else f"{v:.4g} +- {sd:.2g}{unit}"


def part_values(params: list, theta) -> dict:
    """{parameter: value in file units per m/min of feed} of the parts in ``params``."""
    return {n: round(float(t) * _FACTORS[_prefix(n)][0], 6) for n, t in zip(params, theta)
            if n.startswith(tuple(_FACTORS))}


def set_headline(params: dict, axis: str, values: dict, sds: dict | None = None,
                 contribution: dict | None = None) -> None:
    """Put the headline keys and ``parts_per_m_min`` (``parts_sd_per_m_min`` with ``sds``) into a
    finding's ``params``. The headline is the cause part furthest from zero in standard errors
    (``sds`` given and finite), else the one with the largest ``contribution`` (else value)."""
    causes = [n for n in values if n.startswith(_CAUSES)]
    if not causes:
        return
    sds = {n: s for n, s in (sds or {}).items() if s is not None and np.isfinite(s) and s > 0}
    if all(n in sds for n in causes):
        main = max(causes, key=lambda n: abs(values[n]) / sds[n])
    else:
        size = contribution or {n: abs(v) for n, v in values.items()}
        main = max(causes, key=lambda n: size.get(n, 0.0))
    unit = _FACTORS[_prefix(main)][1]
    sd = sds.get(main)
    significant = None if sd is None else bool(abs(values[main]) >= SIGNIFICANT_SD * sd)
    params["headline"] = (f"{_what(main, axis)} {_value(values[main], sd, unit)} per m/min of feed "
                          f"({main}" + ("" if sd is None else
                                        f", {abs(values[main]) / sd:.3g} standard errors from zero")
                          + ")")
    params.update({"headline_component": main, "headline_per_m_min": values[main],
                   "headline_sd_per_m_min": None if sd is None else round(float(sd), 6),
                   "headline_unit": unit, "headline_significant": significant,
                   "parts_per_m_min": dict(values)})
    if sds:
        params["parts_sd_per_m_min"] = {n: round(float(s), 6) for n, s in sds.items() if n in values}


def others_text(params: dict) -> str:
    """The printed words of the parts beside the headline, each with its standard error and
    whether it is significant."""
    values, sds = params.get("parts_per_m_min", {}), params.get("parts_sd_per_m_min", {})
    out = []
    for n, v in values.items():
        if n == params.get("headline_component"):
            continue
        sd = sds.get(n)
        flag = "" if sd is None else (" (significant)" if abs(v) >= SIGNIFICANT_SD * sd else " (not significant)")
        out.append(f"{n} {_value(v, sd, _FACTORS[_prefix(n)][1])}{flag}")
    return "; beside it per m/min: " + ", ".join(out) if out else ""


def quote_standard_errors(findings, model) -> None:
    """Each feed-dependent Abbe finding's parts with the values and standard errors of the model
    written (as MODEL.json gives them, file units), its headline chosen on them; and the standard
    error of its moving centre (``irc_shift_sd_mm_per_m_min``) and angle gain
    (``angle_gain_sd_per_m_min``)."""
    se = model.params.std_errors
    for f in findings:
        if f.effect != "feed_dependent_abbe" or f.candidate is None:
            continue
        names = [n for n in f.candidate.params if n in model.params and n.startswith(tuple(_FACTORS))]
        idx = [model.params.index(n) for n in names]
        to_file = [model.params.specs[i].to_file for i in idx]
        values = {n: round(float(model.params.values[i] * k), 6) for n, i, k in zip(names, idx, to_file)}
        sds = ({} if se is None else
               {n: float(se[i] * k) for n, i, k in zip(names, idx, to_file) if np.isfinite(se[i])})
        for key, comp, nd in (("irc_shift_sd_mm_per_m_min", "irc_shift_component", 4),
                              ("angle_gain_sd_per_m_min", "angle_gain_component", 6)):
            if f.params.get(comp) in sds:
                f.params[key] = round(sds[f.params[comp]], nd)
        causes = [n for n in values if n.startswith(_CAUSES)]
        if all(n in sds and sds[n] > 0 for n in causes):
            set_headline(f.params, f.axis, values, sds)
        else:
            # a cause without a standard error: the headline stays the one chosen on the parts'
            # contributions (values in different units are no measure of which part acts most)
            f.params["parts_per_m_min"] = dict(values)
            if sds:
                f.params["parts_sd_per_m_min"] = {n: round(float(v), 6) for n, v in sds.items()}
