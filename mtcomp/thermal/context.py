"""The thermal state a program is compensated for: temperatures and spindle speed given on the
command line (or a file of readings, :func:`read_temperature_row`: one row, or a time series along
the program's run time, :class:`TemperatureSeries`) become the context of the
model's drift terms (``temp_<name>`` in degC, ``spindle_lag_<tau>`` / ``spindle_heat_<tau>`` in
1000 rpm at steady state), checked against the range of the thermal record the model was fitted on
(MODEL.json's ``info["context_ranges"]``, docs/thermal.md)."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

_LAG = re.compile(r"^spindle_(lag|heat)_\d+(\.\d+)?$")
_TIME = re.compile(r"^time_(h|exp_\d+)$")
_TEMP_COLUMN = re.compile(r"^temp_(.+)_c$")


def parse_assignments(items, flag: str) -> dict:
    """['t1=24.5', ...] -> {'t1': 24.5}; InputError naming ``flag`` on a malformed item."""
    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        try:
            v = float(value)
        except ValueError:
            v = math.nan
        if not sep or not name or not math.isfinite(v):
            raise InputError(f"{flag} {item!r}: write NAME=VALUE with a number, e.g. t1=24.5")
        if name in out:
            raise InputError(f"{flag} {item!r}: {name} is given twice ({out[name]:g} and {v:g})")
        out[name] = v
    return out


@dataclass(frozen=True)
class TemperatureSeries:
    """Readings along the program's run time: ``t_s`` (k,) seconds from the program's start,
    increasing; ``temps`` sensor name -> (k,) degC. Between readings the temperatures are
    interpolated linearly; before the first and after the last the nearest reading holds."""

    t_s: np.ndarray
    temps: dict
    #: (k,) the file's data row of each reading (for messages), None when not from a file
    rows: np.ndarray | None = None

    def at(self, t_s) -> dict:
        """sensor name -> (n,) degC at the times ``t_s`` (n,) seconds."""
        t = np.asarray(t_s, dtype=float)
        return {s: np.interp(t, self.t_s, v) for s, v in self.temps.items()}

    def extremes(self) -> list[dict]:
        """The lowest and the highest reading of every sensor, as two states (for range checks)."""
        return [{s: float(np.min(v)) for s, v in self.temps.items()},
                {s: float(np.max(v)) for s, v in self.temps.items()}]


def read_temperature_row(path) -> tuple[dict | TemperatureSeries, list]:
    """(readings, columns not read) of ``--temperatures FILE``: a CSV file with a header and one
    column ``temp_<name>_c`` per sensor (as in the thermal file). One row: the temperatures while the
    program runs, sensor name -> degC (a blank cell gives no reading). Several rows: a time series
    with a ``t_s`` column (seconds from the program's start, increasing), returned as a
    :class:`TemperatureSeries` (every cell given). Columns other than these (``spindle_rpm``, ...)
    are not read. InputError naming the file and the row otherwise."""
    from ..io.csvtable import read_csv_table
    from ..measurement.thermal_checks import check_unit_columns
    table = read_csv_table(path)
    check_unit_columns(table)       # temp_head_F: a sensor in another unit is refused, not dropped
    names = [n for n in table.names if _TEMP_COLUMN.match(n)]
    other = [n for n in table.names if n not in names and not (n == "t_s" and len(table.rows) > 1)]
    if not names:
        table.fail("no temperature column: expected columns temp_<name>_c (degC), as in the "
                   "thermal file")
    if len(table.rows) > 1:
        if not table.has("t_s"):
            table.fail(f"{len(table.rows)} rows of readings and no t_s column: a time series needs "
                       "the time of each reading (seconds from the program's start); one row gives "
                       "the temperatures while the program runs")
        t = table.floats("t_s")
        _check_series_times(table, t)
        temps = {}
        for name in names:
            v = table.floats(name)
            if not np.all(np.isfinite(v)):
                table.fail(f"column {name}: every reading of a time series must be given",
                           int(np.flatnonzero(~np.isfinite(v))[0]))
            temps[_TEMP_COLUMN.match(name).group(1)] = v
        return TemperatureSeries(t, temps, np.asarray(table.row)), other
    temps = {}
    for name in names:
        v = float(table.floats(name)[0])
        if math.isfinite(v):
            temps[_TEMP_COLUMN.match(name).group(1)] = v
    if not temps:
        table.fail("no temperature in the row: expected columns temp_<name>_c (degC) with a value, "
                   "as in the thermal file", 0)
    return temps, other


def _check_series_times(table, t) -> None:
    """InputError naming the first row of a series whose ``t_s`` is not a number, goes back (its
    value and the row before's, as the thermal record reader says) or repeats the row before's."""
    from ..measurement.thermal_checks import check_time_order
    blank = np.flatnonzero(~np.isfinite(t))
    if blank.size:
        table.fail("column t_s: no time (blank or not a number): a series gives the time of every "
                   "reading, in seconds, increasing from row to row", int(blank[0]))
    check_time_order(table, t)
    same = np.flatnonzero(np.diff(t) == 0)
    if same.size:
        i = int(same[0]) + 1
        table.fail(f"column t_s: {t[i]:.10g} s repeats the row before's: a series' readings are at "
                   "increasing times", i)


def missing_sensors(fitted, given) -> tuple[list, list]:
    """(the sensors the model's tool-tip drift reads that ``given`` (sensor names) leaves out, all
    the sensors it reads)."""
    features = [f for t in _drift_terms(fitted.model)[0] for f in t.features]
    temps = list(dict.fromkeys(f[5:] for f in features if f.startswith("temp_")))
    return [s for s in temps if s not in given], temps


def _every_sensor(temps) -> str:
    """Why a state must give every sensor of ``temps``, the sensors the drift reads."""
    return (f"the model's thermal drift reads sensor(s) {', '.join(temps)}: give every sensor's "
            "temperature (one left out is not taken at its mean over the record: the coefficients "
            "of correlated sensors are fitted together, and one sensor's without the others' "
            "corrects a drift that is not there)")


def check_readings(fitted, readings, path, flags=(), extrapolate: bool = False) -> None:
    """InputError naming the readings file ``path`` (``--temperatures``), the row and the column of
    the first reading beyond the range the model's thermal record spans (unless ``extrapolate``).
    ``readings``: what :func:`read_temperature_row` returned (one row, or a series); the sensors of
    ``flags`` are given on the command line, which wins, and are not checked here. InputError too
    (naming the column; a series' header) for a sensor the model's drift reads that neither the
    file (no column, a blank cell) nor ``flags`` gives."""
    temps_given = readings.temps if isinstance(readings, TemperatureSeries) else readings
    missing, temps = missing_sensors(fitted, set(temps_given) | set(flags))
    if missing:
        series = isinstance(readings, TemperatureSeries)
        columns = ", ".join(f"temp_{s}_c" for s in missing)
        raise InputError(f"no {'column ' + columns if series else 'reading in column(s) ' + columns} "
                         f"(nor --temperature {missing[0]}=...): {_every_sensor(temps)}",
                         path, row=0 if series else None)
    ranges = fitted.info.get("context_ranges") if isinstance(fitted.info, dict) else None
    if extrapolate or not isinstance(ranges, dict):
        return
    if isinstance(readings, TemperatureSeries):
        temps = readings.temps
        rows = readings.rows if readings.rows is not None else np.arange(1, len(readings.t_s) + 1)
    else:
        temps, rows = {s: np.array([v]) for s, v in readings.items()}, np.array([1])
    for sensor, v in temps.items():
        rng = ranges.get(f"temp_{sensor}")
        if sensor in flags or not rng:
            continue
        bad = np.flatnonzero((v < float(rng[0])) | (v > float(rng[1])))
        if bad.size:
            value = float(v[bad[0]])
            _check_range(f"column temp_{sensor}_c: temperature of sensor {sensor}:", value, "degC", rng,
                         False, path, _degf_hint(value, rng), row=int(rows[bad[0]]))


def has_tip_drift(model) -> bool:
    """The model has a drift term that moves the tool tip (a thermal record's channel mapped to an
    axis)."""
    return bool(_drift_terms(model)[0])


def time_driven(model) -> bool:
    """The model's tool-tip drift reads time alone (a steady ``time_h`` or settling ``time_exp_<tau>``
    drift since its thermal record began): no temperature or spindle speed moves it."""
    features = [f for t in _drift_terms(model)[0] for f in t.features]
    return bool(features) and all(_TIME.match(f) for f in features)


#: the sentence for a drift in time: compensate is told no time, and nothing else moves it
TIME_DRIVEN = ("the model's thermal drift is a drift in time since its thermal record began (diagnose "
               "chose a steady or settling drift in time): when in that time a program runs is not "
               "known, and no temperature or spindle speed moves it, so compensate does not correct "
               "it (diagnose's report lists the drift models it compared: one driven by "
               "temperatures or spindle speed is one compensate can follow)")


def _drift_terms(model):
    from ..models.terms import ChannelDrift, ThermalDrift
    tip = [t for t in model.terms if isinstance(t, ThermalDrift)]
    channel = [t for t in model.terms if isinstance(t, ChannelDrift)]
    return tip, channel


def _check_range(what: str, value: float, unit: str, rng, extrapolate: bool, source, hint: str = "",
                 row: int | None = None):
    """'' inside ``rng`` ([lowest, highest]) or without one; beyond it: InputError, or with
    ``extrapolate`` the words that say so."""
    if not rng:
        return ""
    lo, hi = (float(x) for x in rng)
    if lo <= value <= hi:
        return ""
    span = f"{lo:.4g} to {hi:.4g} {unit}"
    if not extrapolate:
        raise InputError(f"{what} {value:g} {unit} is outside the range the model's thermal record "
                         f"spans ({span}){hint}: refused; give --extrapolate to correct beyond it",
                         source, row=row)
    return f" (beyond the record's {span})"


def _degf_hint(value, rng) -> str:
    """A clause saying what the value (the median of an array of readings) would be in degC if it was
    written in degF, when that falls inside ``rng`` (a likely slip); '' otherwise."""
    v = np.asarray(value, dtype=float)
    c = (float(np.median(v)) - 32.0) / 1.8 if v.size else math.nan
    if not (rng and float(rng[0]) <= c <= float(rng[1])):
        return ""
    return (f"; as degF {'it' if v.size == 1 else 'their median'} would be {c:.3g} degC, inside it: "
            "temperatures are in degC")


def thermal_context(fitted, temperatures: dict | None = None, spindle_rpm: float | None = None,
                    extrapolate: bool = False, source=None, every_sensor: bool = True
                    ) -> tuple[dict, str]:
    """(context values to use, one sentence saying what is assumed) for the drift terms of
    ``fitted`` (a FittedModel). ``temperatures``: sensor name -> degC; ``spindle_rpm``: the speed the
    spindle has run at long enough to reach steady state. A state given must give every sensor the
    drift reads, else InputError naming the ones left out (never taken at the record's mean: the
    coefficients of correlated sensors are large and opposite), unless ``every_sensor`` is False
    (the caller gives the rest along a series and checks them itself).

    InputError (naming ``source``, the model file, when given) for a sensor or a spindle speed the
    model's tool-tip drift does not use, for a thermal state given to a model whose drift maps to no
    machine axis (it would correct nothing), and, unless ``extrapolate``, for a temperature or speed
    outside the range of the record (``info["context_ranges"]``)."""
    tip, channel = _drift_terms(fitted.model)
    given = bool(temperatures) or spindle_rpm is not None
    if channel and not tip:
        chans = ", ".join(c for t in channel for c in t.channels)
        if given:
            raise InputError(f"a temperature or spindle speed was given, but the model's thermal drift "
                             f"reads channels {chans}, none of which maps to a machine axis, so it "
                             "corrects nothing: diagnose the thermal record again with --channel-axis "
                             "NAME=AXIS (or a column axis_<name> in it)", source)
        return {}, (f"thermal drift not compensated: the model's drift reads channels {chans}, none of "
                    "which maps to a machine axis")
    features = [f for t in tip for f in t.features]
    temps = list(dict.fromkeys(f[5:] for f in features if f.startswith("temp_")))
    lags = list(dict.fromkeys(f for f in features if _LAG.match(f)))
    ranges = fitted.info.get("context_ranges") if isinstance(fitted.info, dict) else None
    ranges = ranges if isinstance(ranges, dict) else None
    out, beyond = {}, {}
    if given and time_driven(fitted.model):
        raise InputError(f"a temperature or spindle speed was given, but {TIME_DRIVEN}", source)
    for sensor, v in (temperatures or {}).items():
        if sensor not in temps and f"dtemp_{sensor}" in features:
            raise InputError(f"temperature {sensor}: the model's drift reads that sensor's rise since "
                             f"the first reading of each file it was fitted on (dtemp_{sensor}), "
                             "which has no value while a program runs: diagnose one thermal record, "
                             "alone or beside the geometric files (join the records of one set-up "
                             "into one file in time order), for a drift compensate can follow",
                             source)
        if sensor not in temps:
            raise InputError(f"temperature {sensor}: the model has no drift term that reads that "
                             f"sensor (it reads: {', '.join(temps) or 'none'})", source)
        rng = (ranges or {}).get(f"temp_{sensor}")
        beyond[sensor] = _check_range(f"temperature of sensor {sensor}:", float(v), "degC", rng,
                                      extrapolate, source, _degf_hint(float(v), rng))
        out[f"temp_{sensor}"] = float(v)
    if spindle_rpm is not None:
        if not math.isfinite(spindle_rpm) or spindle_rpm < 0:
            raise InputError(f"--spindle-rpm must be a speed of 0 or more, got {spindle_rpm:g}")
        if not lags:
            raise InputError("--spindle-rpm: the model has no drift term that reads spindle heat", source)
        rpm_beyond = _check_range("--spindle-rpm", float(spindle_rpm), "rpm",
                                         (ranges or {}).get("spindle_rpm"), extrapolate, source)
        out.update({n: spindle_rpm / 1000.0 for n in lags})
    missing = [s for s in temps if f"temp_{s}" not in out]
    if given and every_sensor and missing:
        raise InputError(f"no temperature of sensor(s) {', '.join(missing)} is given "
                         f"(--temperature NAME=DEGC): {_every_sensor(temps)}", source)
    if not temps and not lags:
        return out, ""
    parts = []
    if temps:
        done = [s for s in temps if f"temp_{s}" in out]
        if done:
            parts.append("temperatures " + ", ".join(f"{s}={out['temp_' + s]:g} degC{beyond[s]}"
                                                      for s in done))
        if missing:     # with every_sensor False the caller's series gives them; else none given
            parts.append(f"{'other ' if done else ''}temperatures ({', '.join(missing)}) "
                         + ("as the readings give them" if given else "not given"))
    if lags:
        parts.append(f"spindle heat at steady state of {spindle_rpm:g} rpm{rpm_beyond}"
                     if spindle_rpm is not None else "spindle stopped for long (no spindle heat)")
    if given and ranges is None:
        parts.append("the model file records no range of its thermal record: the values given are "
                     "not checked against it")
    return out, "thermal drift assumed: " + "; ".join(parts)


def probed_state(fitted, cut_sensors, cut_rpm, probed_temperatures=None, probed_rpm=None,
                 extrapolate: bool = False, source=None) -> tuple[dict | None, str]:
    """(the drift terms' context at the part's datum as it was probed, None when no drift is
    corrected; the line saying which reference the drift is corrected from, '' when no drift is
    corrected). The probe put the drift of its time into the work offset, so a block corrects the
    drift while it runs less the drift at probing. ``cut_sensors``: the sensors the state while the
    program runs gives (flags, a row or a series); ``cut_rpm``: its spindle speed or None;
    ``probed_temperatures`` (sensor -> degC) and ``probed_rpm``: the state at probing, which must
    give what the running state gives; neither given: the thermal record's first reading
    (:func:`record_reference`). InputError (naming ``source``) otherwise, and for a probed state
    given to a model whose drift compensate does not correct."""
    probed_temperatures = probed_temperatures or {}
    given = bool(probed_temperatures) or probed_rpm is not None
    cut_given = bool(cut_sensors) or cut_rpm is not None
    if not given and not (cut_given and has_tip_drift(fitted.model)):
        return None, ""
    if not cut_given:
        raise InputError("a thermal state at probing (--probed-at-temperature, "
                         "--probed-at-spindle-rpm) was given without the state while the program "
                         "runs (--temperature, --temperatures, --spindle-rpm): no drift is "
                         "corrected without it", source)
    if not given:
        return record_reference(fitted, cut_sensors, cut_rpm, source)
    if (cut_rpm is None) != (probed_rpm is None):
        raise InputError("--spindle-rpm and --probed-at-spindle-rpm go together: give the spindle's "
                         "state both while the program runs and at probing, or neither", source)
    for sensor in cut_sensors:
        if sensor not in probed_temperatures:
            raise InputError(f"--probed-at-temperature gives no temperature of sensor {sensor}, "
                             "which the state while the program runs gives: give every such "
                             "sensor's temperature at probing", source)
    for sensor in probed_temperatures:
        if sensor not in cut_sensors:
            raise InputError(f"--probed-at-temperature {sensor}: the state while the program runs "
                             f"gives no temperature of sensor {sensor} (give it with --temperature)",
                             source)
    try:
        context, sentence = thermal_context(fitted, probed_temperatures, probed_rpm, extrapolate,
                                            source)
    except InputError as e:       # the state at probing named: its messages say --spindle-rpm
        raise InputError("at probing: " + e.message.replace("--spindle-rpm",
                                                             "--probed-at-spindle-rpm"),
                         e.path) from None
    return context, ("thermal drift referenced to the datum's probing (the drift since then is "
                     "corrected): at probing " + sentence.partition(": ")[2])


def record_reference(fitted, cut_sensors, cut_rpm, source=None) -> tuple[dict, str]:
    """(the drift terms' context at the part's datum when no state at probing is given, the line
    saying so): the thermal record's first reading (``info["thermal_first_reading"]``, written by
    diagnose), so that the drift since then is corrected and never the drift model's absolute value,
    whose constant holds the set-up zero of the record's probe (what the data leave undetermined).
    Only what the state while the program runs gives is taken from it (``cut_sensors``, the spindle
    heat when ``cut_rpm`` is given): the rest is at the same value at the datum and while the
    program runs. A model file without that reading (an older mtcomp) is referenced to the
    record's mean temperatures (its context defaults as read from the file: called before the
    running state is written into them) and a spindle stopped long; InputError
    (naming ``source``) for a temperature it holds no reference of."""
    features = [f for t in _drift_terms(fitted.model)[0] for f in t.features]
    temps = [f for f in features if f.startswith("temp_") and f[5:] in cut_sensors]
    lags = [f for f in features if _LAG.match(f)] if cut_rpm is not None else []
    flag = "--probed-at-temperature" if temps else "--probed-at-spindle-rpm"
    info = fitted.info if isinstance(fitted.info, dict) else {}
    first = info.get("thermal_first_reading")
    record = info.get("thermal_record") or "the thermal record"
    temp_text = lambda state: ", ".join(f"{f[5:]}={state[f]:.5g}" for f in temps) + " degC"  # noqa: E731
    if isinstance(first, dict) and all(f in first for f in temps + lags):
        state = {f: float(first[f]) for f in temps + lags}
        said = ([temp_text(state)] if temps else []) + (
            [f"spindle heat of {1e3 * state[lags[0]]:g} rpm"] if lags else [])
        return state, (f"thermal drift referenced to the record's first reading ({record}: "
                       f"{'; '.join(said)}): the drift since then is corrected (a probe's set-up "
                       f"zero is not); give {flag} if the datum was probed warm")
    missing = [f for f in temps if f not in fitted.context_defaults]
    if missing:
        raise InputError(f"the model file records neither the first reading of its thermal record "
                         f"nor a reference temperature of sensor {missing[0][5:]}: give {flag} "
                         "with the temperatures at which the part's datum was probed", source)
    state = {**{f: float(fitted.context_defaults[f]) for f in temps}, **{f: 0.0 for f in lags}}
    said = ([f"the record's mean temperatures {temp_text(state)}"] if temps else []) + (
        ["a spindle stopped long"] if lags else [])
    return state, (f"thermal drift referenced to {' and '.join(said)}: the model file records no "
                   f"first reading of a thermal record ({_why_no_first_reading(info, record)}); give "
                   f"{flag} with the state at which the datum was probed")


def _why_no_first_reading(info: dict, record: str) -> str:
    """Why a model file with drift terms holds no ``thermal_first_reading``: an older mtcomp (no
    ``thermal_record`` either, which mtcomp writes with it, but a record's ``context_ranges`` or a
    thermal diagnosis), a record that chose no drift model (its ranges empty: the drift is the other
    files'), or a drift fitted without a record (identify, geometric files' spindle speeds)."""
    ranges = info.get("context_ranges")
    if "thermal_record" in info and isinstance(ranges, dict) and not ranges:
        return (f"its thermal record {record} chose no drift model, so the drift it corrects was "
                "fitted on its other files, whose readings have no first one")
    if "thermal_record" not in info and (ranges is not None
                                         or info.get("fitted_by") == "mtcomp diagnose (thermal drift)"):
        return f"{record}; an older mtcomp wrote it: diagnose the record again to have it"
    return ("its drift was fitted without a thermal record (by identify, or on the spindle speeds of "
            "geometric files), which would give one")


def _refuse_degf(data, sensor: str, v, rng) -> None:
    """InputError naming ``data``'s file, the first row beyond ``rng`` and the column of ``sensor``
    when the median of its readings ``v`` lies outside ``rng`` read in degC and inside it read in degF:
    a column of degF readings under ``temp_<sensor>_c``, not a state beyond the record (as compensate
    refuses a reading so)."""
    finite = v[np.isfinite(v)]
    if not rng or not finite.size:
        return
    lo, hi = (float(x) for x in rng)
    med = float(np.median(finite))
    hint = _degf_hint(finite, rng)
    if lo <= med <= hi or not hint:
        return
    first = int(np.flatnonzero((v < lo) | (v > hi))[0])
    raise InputError(f"column temp_{sensor}_c: temperatures of sensor {sensor}: {finite.min():.5g} to "
                     f"{finite.max():.5g} degC, median {med:.4g} degC, outside the range the model's "
                     f"thermal record spans ({lo:.4g} to {hi:.4g} degC){hint}: refused (write them in "
                     "degC: (F - 32) / 1.8)", data.path, row=int(data.row[first]))


def record_state_note(fitted, data) -> str:
    """The sentence on the rows of a measurement file ``data`` whose temperatures or spindle speed
    lie outside the range the model's thermal record spans (``info["context_ranges"]``), each sensor
    the model's drift reads checked alone, as compensate checks a thermal state; '' when none does
    (or the model records no range). InputError for a thermal file without a column
    ``temp_<name>_c`` of a sensor the drift reads: the sensor would be taken at its mean over the
    record in every row."""
    tip, channel = _drift_terms(fitted.model)
    features = [f for t in (*tip, *channel) for f in t.features]
    temps = list(dict.fromkeys(f[5:] for f in features if f.startswith("temp_")))
    given = data.context.temperatures
    missing = [s for s in temps if s not in given]
    if missing and getattr(data, "kind", "") == "thermal":
        raise InputError(f"no column {', '.join(f'temp_{s}_c' for s in missing)}: the model's thermal "
                         f"drift reads sensor(s) {', '.join(missing)} (it reads {', '.join(temps)}); "
                         "give every sensor's readings, in degC", data.path, row=0)
    ranges = fitted.info.get("context_ranges") if isinstance(fitted.info, dict) else None
    out = np.zeros(len(data), dtype=bool)
    if not isinstance(ranges, dict):
        return ""
    parts = []
    checks = [(s, f"temp_{s}", given[s], "degC") for s in temps if s in given]
    for sensor, key, v, _ in checks:
        _refuse_degf(data, sensor, np.asarray(v, dtype=float), ranges.get(key))
    rpm = getattr(data.context, "spindle_rpm", None)
    if any(_LAG.match(f) for f in features) and rpm is not None:
        # a blank speed is what the file does not give (a geometric file has none): not checked
        checks.append(("spindle_rpm", "spindle_rpm", np.asarray(rpm, dtype=float), "rpm"))
    for name, key, v, unit in checks:
        rng = ranges.get(key)
        if not rng:
            continue
        lo, hi = (float(x) for x in rng)
        beyond = (np.asarray(v, dtype=float) < lo) | (np.asarray(v, dtype=float) > hi)
        if beyond.any():
            out |= beyond
            w = np.asarray(v, dtype=float)[beyond]
            parts.append(f"{name} {int(beyond.sum())} row(s) at {w.min():.5g} to {w.max():.5g} {unit} "
                         f"against {lo:.5g} to {hi:.5g}"
                         + (_degf_hint(w, rng) if unit == "degC" else ""))
    if not out.any():
        return ""
    return (f"{data.path}: {int(out.sum())} of {len(data)} row(s) lie outside the thermal state the "
            f"model's record spans ({', '.join(parts)}): the drift model carries on linearly there, "
            "beyond what it saw; their standard errors take it to hold and do not size that "
            "(compensate refuses such a state without --extrapolate)")
