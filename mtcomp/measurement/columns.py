"""What a measurement file's columns and values say beyond what the readers take (docs/measurements.md).

A file may carry columns mtcomp does not read (an operator's note, a sensor's temperature); they
are kept and ``mtcomp predict`` repeats them. But a column that looks like one mtcomp reads,
misspelt (``tool_length_mm``, ``stylus_mm``, ``dx_umm``), is almost always that column under the
wrong name: read as an extra column, its values would be ignored without a word (a points file's
stylus lengths replaced by the machine's tool length in every row). So:

* :func:`check_columns` refuses a column that names the tool length another way (``tool_length_mm``,
  ``stylus_mm``, ``probe_length_mm`` ...: "did you mean tool_mm") or lies within a letter or two of
  a column the file's kind reads and lacks (``difflib`` ratio at least :data:`MISSPELT_RATIO`).
* :func:`check_axis_units` refuses an axis position in another unit (``c_rad``, ``x_in``) with no
  ``c_deg`` or ``x_mm`` beside it.
* :func:`check_columns` also refuses any other quantity the file's kind reads written in another
  unit (``feed_mm_s``, ``t_min``, ``value_nm``, ``length_in``) with no column of mtcomp's unit beside
  it: read as an extra column, the quantity would vanish with only a note (a laser file's feeds in
  ``feed_mm_s`` left every run at an unknown feed, and a time drift was named in their place).
* :func:`file_notes` says, per file: the columns mtcomp does not read; that a points file without
  ``tool_mm`` is taken at the machine's tool length in every row; and when every deviation of a
  points or cmm file is smaller than a machine's errors and an instrument's noise over the span of
  its positions (values in mm written under ``*_um`` columns: the unit check of
  :func:`mtcomp.measurement.units.unit_check`, below max(0.05 um, 0.5 ppm of the span) over 100 mm
  or more), when every bar length of a ball-bar file is under an inch (a file in inches), and when
  a laser file's targets are whole mm only times 25.4 (targets in inches, :func:`_inch_targets`),
  and when a points or cmm file's positions are (:func:`_inch_positions`); when a rotary axis's
  angles (``b_deg``...) are whole degrees only once read as radians (:func:`_radian_angles`), and
  when the machine has a rotary axis the file gives no column for (taken at 0 in every row).
"""
from __future__ import annotations

import difflib
import re

import numpy as np

from ..errors import InputError
from ..machine import AXIS_ORDER
from .thermal_checks import thermal_notes
from .units import UM, UNIT_CHECK_FLOOR_UM, unit_check, unit_limit_um

#: a column this close (difflib ratio) to one the file's kind reads and lacks is taken as misspelt
MISSPELT_RATIO = 0.85
#: names of the tool length a user may write for ``tool_mm``
_TOOL_ALIAS = re.compile(r"^(tool|stylus|probe)_?(len|length)(_mm)?$|^(stylus|probe)_mm$")

_XYZ = ("x_mm", "y_mm", "z_mm")
_ABC = ("a_deg", "b_deg", "c_deg")
_COMMON = ("kind", "feed_mm_min", "t_s", "run", "spindle_rpm", *(f"dir_{a.lower()}" for a in AXIS_ORDER))
#: the columns each kind's reader takes (beside the patterns of :data:`_PATTERNS`)
KNOWN = {
    "points": (*_XYZ, *_ABC, "tool_mm", "dx_um", "dy_um", "dz_um", "dn_um", "nx", "ny", "nz"),
    "laser": ("axis", "component", "target_mm", "target_deg", "dir", "value_um", "value_urad", *_XYZ,
              *_ABC, "optic_x_mm", "optic_y_mm", "optic_z_mm", "seq"),
    "ballbar": (*_XYZ, *_ABC, "table_ball_x_mm", "table_ball_y_mm", "table_ball_z_mm",
                "tool_ball_x_mm", "tool_ball_y_mm", "tool_ball_z_mm", "length_mm"),
    "cmm": (*_XYZ, "nx", "ny", "nz", "dn_um"),
    "thermal": (),
    "velocity": ("axis", *_XYZ, "m_x_mm", "m_y_mm", "m_vx_mm_min", "m_vy_mm_min",
                 "n_x_mm", "n_y_mm", "n_vx_mm_min", "n_vy_mm_min"),
}
#: column patterns read in every file (temperatures), in thermal files (channels and their axes),
#: and mtcomp's own prediction columns (``mtcomp predict`` writes them; a file read back keeps them)
_PATTERNS = (re.compile(r"^temp_.+_c$"), re.compile(r"^pred_.+$"))
_THERMAL = (re.compile(r"^disp_.+_um$"), re.compile(r"^axis_.+$"))
#: deviation columns whose values the unit check reads
_DEVIATIONS = ("dx_um", "dy_um", "dz_um", "dn_um")
#: an axis position column in another unit than mtcomp's (``c_rad``, ``x_in``, ``z_m``)
_AXIS_OTHER_UNIT = re.compile(r"^([xyzabc])_(rad|mrad|urad|grad|gon|rev|in|inch|inches|m|cm)$")


def _known(kind: str, name: str) -> bool:
    if name in _COMMON or name in KNOWN.get(kind, ()):
        return True
    patterns = _PATTERNS + (_THERMAL if kind == "thermal" else ())
    return any(p.match(name) for p in patterns)


def unknown_columns(kind: str, names) -> list[str]:
    """The columns of ``names`` (lower case) a file of ``kind`` does not read, in file order."""
    return [n for n in names if n and not _known(kind, n)]


#: the units of the columns mtcomp reads (their names' suffixes), with what each is a unit of, its
#: words, and the other spellings of that quantity's units a file may carry instead
_UNITS = {"mm_min": ("speed", "mm/min"), "mm": ("length", "mm"), "um": ("length", "um"),
          "deg": ("angle", "degrees"), "urad": ("angle", "urad"), "s": ("time", "seconds"),
          "rpm": ("turning speed", "rev/min")}
_OTHER_UNITS = {
    "speed": ("mm_s", "mm_sec", "mm_per_s", "mm_per_min", "mmpm", "mmps", "m_min", "m_s", "m_per_min",
              "in_min", "in_s", "ipm", "ips", "um_s", "um_min"),
    "length": ("m", "cm", "nm", "in", "inch", "inches", "mil", "mils", "thou", "micron", "microns", "mu"),
    "angle": ("rad", "mrad", "arcsec", "asec", "arcmin", "grad", "gon", "rev"),
    "time": ("sec", "secs", "ms", "min", "mins", "minutes", "h", "hr", "hrs", "hour", "hours"),
    "turning speed": ("rps", "hz", "rad_s", "deg_s", "rev_s"),
}
#: what the common columns read, in words (others are named by their column)
_QUANTITY = {"feed": "the feed", "t": "the time of each reading", "value": "the reading",
             "target": "the target", "length": "the bar length", "tool": "the tool or stylus length",
             "spindle": "the spindle speed"}
_AXIS_LETTERS = ("x", "y", "z", "a", "b", "c")


def _meant_in_other_unit(kind: str, name: str, names) -> tuple | None:
    """(column, unit in words, quantity) when ``name`` is a column ``kind`` reads (or every file
    reads) written in another unit of the same quantity, and that column is not in ``names``."""
    for column in (*_COMMON, *KNOWN.get(kind, ())):
        unit = next((u for u in _UNITS if column.endswith("_" + u)), None)
        if unit is None:
            continue
        stem = column[:-len(unit) - 1]
        quantity = _UNITS[unit][0]
        words = (*_OTHER_UNITS[quantity], *(u for u, (q, _) in _UNITS.items() if q == quantity))
        if name.startswith(stem + "_") and name[len(stem) + 1:] in words:
            same = [c for c in (*_COMMON, *KNOWN.get(kind, ())) if c.startswith(stem + "_")
                    and c[len(stem) + 1:] in _UNITS]
            if any(c in names for c in same):
                return None                 # beside the column mtcomp reads: an extra column
            what = _QUANTITY.get(stem) or (f"the {stem.upper()} axis's position" if stem in _AXIS_LETTERS
                                           else f"the quantity of {column}")
            return column, _UNITS[unit][1], what
    return None


def check_columns(table, kind: str) -> None:
    """InputError (row 0, the header) for a column that looks like one this kind reads, misspelt
    or in another unit: a quantity the kind reads in another unit (``feed_mm_s`` for
    ``feed_mm_min``, ``t_min`` for ``t_s``), a name of the tool length other than ``tool_mm`` in a
    points file, or a name within :data:`MISSPELT_RATIO` of a column the kind reads and the file
    lacks."""
    names = table.names
    for name in unknown_columns(kind, names):
        other = _meant_in_other_unit(kind, name, names)
        if other is not None:
            column, unit, what = other
            given = table.header[names.index(name)].strip()
            raise InputError(f"column {given}: mtcomp reads {what} as {column}, in {unit}, and does "
                             f"not read {given}; convert the values to {unit} and rename the column",
                             table.path, row=0)
        meant = None
        if kind == "points" and "tool_mm" not in names and _TOOL_ALIAS.match(name):
            meant = "tool_mm"
        else:
            absent = [k for k in KNOWN.get(kind, ()) if k not in names]
            close = difflib.get_close_matches(name, absent, n=1, cutoff=MISSPELT_RATIO)
            meant = close[0] if close else None
        if meant is not None:
            what = (" (the tool or stylus length of each row, mm; blank: the machine's "
                    "tool_length_mm)" if meant == "tool_mm" else "")
            raise InputError(f"column {name}: did you mean {meant}{what}? mtcomp does not read "
                             f"{name}; rename the column", table.path, row=0)


def check_axis_units(table) -> None:
    """InputError (row 0, the header) for an axis position column in another unit, ``c_rad`` or
    ``x_in`` with no ``c_deg`` or ``x_mm`` beside it: read as a column mtcomp does not read, the
    axis would be taken at 0 in every row (or the file refused for a column it lacks)."""
    for name in table.names:
        m = _AXIS_OTHER_UNIT.match(name)
        if m is None:
            continue
        letter = m.group(1)
        column = f"{letter}_{'deg' if letter in 'abc' else 'mm'}"
        if column in table.names:
            continue
        unit = "degrees" if letter in "abc" else "mm"
        raise InputError(f"column {name}: mtcomp reads the {letter.upper()} axis's position as "
                         f"{column}, in {unit}, and does not read {name}; convert the values and "
                         "rename the column",
                         table.path, row=0)


def file_notes(machine, datasets) -> list[str]:
    """One sentence per finding in each file (module docstring): columns not read, a points file
    taken at the machine's tool length, deviations that look like mm under ``*_um``, lengths or
    laser targets that look like inches."""
    notes = []
    for data in datasets:
        data = getattr(data, "data", data)          # a measurement model's file
        header = [h.strip().lower() for h in getattr(data, "header", ())]
        if not header or not len(data):
            continue
        extra = unknown_columns(data.kind, header)
        if extra:
            notes.append(f"{data.path}: column(s) {', '.join(extra)} not read by mtcomp (a {data.kind} "
                         "file's columns are in docs/measurements.md); kept as they are")
        if data.kind == "points" and "tool_mm" not in header:
            notes.append(f"{data.path}: no column tool_mm: every row is taken at the machine's tool "
                         f"length, {machine.tool_length:g} mm (its tool_length_mm); give tool_mm if the "
                         "stylus or tool was another length")
        line = (_inch_positions(data) or _mm_under_um(data, header) or _short_bar(data)
                or _inch_targets(data))
        notes += [n for n in (line, _radian_angles(data), _rotary_at_zero(machine, data),
                              _moving_axis_column(data)) if n]
        line = _slow_feeds(data, header)
        if line:
            notes.append(line)
        notes += thermal_notes(data)
    return notes


#: no ball bar is shorter (mm): a file whose every length is below it is likely in inches
SHORTEST_BAR_MM = 25.4


def _short_bar(data) -> str | None:
    """The sentence when every bar length of a ball-bar file is below :data:`SHORTEST_BAR_MM`."""
    length = np.asarray(getattr(data, "length", ()), dtype=float) if data.kind == "ballbar" else ()
    length = length[np.isfinite(length)] if len(length) else length
    if not len(length) or length.max() >= SHORTEST_BAR_MM:
        return None
    return (f"{data.path}: every length_mm is below {SHORTEST_BAR_MM:g} mm (largest "
            f"{length.max():.4g}): no ball bar is that short; a file in inches? mtcomp reads mm")


#: a file whose every feed is below this (mm/min) is likely in mm/s: 1000 to 6000 mm/min, the usual
#: feeds of laser and ball-bar runs, are 16.7 to 100 mm/s
SLOWEST_FEED_MM_MIN = 100.0


def _slow_feeds(data, header) -> str | None:
    """The sentence when every feed of a file is below :data:`SLOWEST_FEED_MM_MIN` (feeds in mm/s
    written under ``feed_mm_min``?), else None: a plausibility note, never a refusal."""
    if "feed_mm_min" not in header:
        return None
    feed = np.asarray(data.context.feed, dtype=float)
    feed = feed[np.isfinite(feed) & (feed > 0)]
    if not feed.size or feed.max() >= SLOWEST_FEED_MM_MIN:
        return None
    return (f"{data.path}: every feed_mm_min is below {SLOWEST_FEED_MM_MIN:g} mm/min ({feed.min():.4g} to "
            f"{feed.max():.4g}), slower than laser and ball-bar runs are made: feeds in mm/s? mtcomp reads "
            "feed_mm_min in mm/min (mm/s times 60)")


#: a laser file's targets that are whole mm once multiplied by 25.4 (within this, mm), and not all
#: multiples of 0.1 mm as written, are inches under ``target_mm``
INCH_TARGET_TOL_MM = 0.01


def _inch_targets(data) -> str | None:
    """The sentence when a laser file's targets look like inches written under ``target_mm``: each
    times 25.4 is a whole number of mm (within :data:`INCH_TARGET_TOL_MM`: 0.0001 in written), and
    as written they are not all multiples of 0.1 mm; else None. It gives the figure that follows:
    how fast the positioning error changes along the axis as read (um per m), against what it
    would be in inches. Judged on the targets, not on that figure: real short-stroke stages change
    by 1200 to 4200 um/m peak to peak over 8 to 40 mm (periodic errors, drift), as fast as a run
    in inches seems to."""
    if data.kind != "laser" or not len(data.target):
        return None
    linear = ~np.isin(data.axis, list("ABC")) & np.isfinite(data.target)
    t = np.unique(data.target[linear])
    if not _look_like_inches(t):
        return None
    span = float(np.ptp(t))
    rows = linear & np.isfinite(data.value) & ~data.angular
    change = float(np.ptp(data.value[rows])) / UM if rows.any() else 0.0
    return (f"{data.path}: targets {t[0]:g} to {t[-1]:g} are whole mm only times 25.4 "
            f"({t[0] * 25.4:.0f} to {t[-1] * 25.4:.0f}): targets in inches? target_mm is read in mm, so the "
            f"readings change by {change:.3g} um over {span:.4g} mm ({change / span * 1e3:.0f} um/m as read, "
            f"{change / (span * 25.4) * 1e3:.0f} um/m with the targets in inches); multiply inches by 25.4")


def _look_like_inches(values) -> bool:
    """Whether distinct positions (at least 3, spanning something) read in mm are whole mm only once
    multiplied by 25.4 (within :data:`INCH_TARGET_TOL_MM`) and, as written, not all multiples of
    0.1 mm: positions in inches under a ``*_mm`` column."""
    t = np.unique(np.asarray(values, dtype=float))
    t = t[np.isfinite(t)]
    if t.size < 3 or not np.ptp(t) > 0:
        return False
    whole_in_inches = np.all(np.abs(t * 25.4 - np.round(t * 25.4)) < INCH_TARGET_TOL_MM)
    tenths_in_mm = np.all(np.abs(t * 10.0 - np.round(t * 10.0)) < 1e-6)
    return bool(whole_in_inches and not tenths_in_mm)


def _inch_positions(data) -> str | None:
    """The sentence when a points or cmm file's positions look like inches under ``x_mm``,
    ``y_mm`` or ``z_mm`` (:func:`_look_like_inches`, axis by axis: one column converted and the
    others not is the same mistake), else None: a plausibility note, never a refusal. Such a
    column spans 1/25.4 of the travel it was measured over, so its errors are read as changing
    25.4 times as fast as they do."""
    if data.kind not in ("points", "cmm") or not len(getattr(data, "xyz", ())):
        return None
    axes = [k for k in range(3) if _look_like_inches(data.xyz[:, k])]
    if not axes:
        return None
    names = ", ".join(f"{'xyz'[k]}_mm" for k in axes)
    spans = ", ".join(f"{np.nanmax(data.xyz[:, k]) - np.nanmin(data.xyz[:, k]):.4g}" for k in axes)
    return (f"{data.path}: the positions ({names}) are whole mm only times 25.4 (spans {spans} mm as "
            "read): positions in inches? x_mm, y_mm, z_mm are read in mm; multiply inches by 25.4")


def _moving_axis_column(data) -> str | None:
    """The sentence when a laser row's static column for its own moving axis (``x_mm`` in a row of
    X) holds another position than its target, else None: the moving axis stands at its target
    (the column is not read there), so the file may be a run of another axis labelled with this
    one (a Y run at X -400 written as axis X) or have its columns mixed up (a note)."""
    if data.kind != "laser" or not len(data):
        return None
    for k, letter in enumerate("XYZ"):
        static = data.xyz[:, k]
        bad = np.flatnonzero((data.axis == letter) & np.isfinite(static)
                             & (np.abs(static - data.target) > 1e-6))
        if bad.size:
            i = int(bad[0])
            return (f"{data.path}: row {i + 1}: column {letter.lower()}_mm gives {static[i]:g} for the "
                    f"moving axis {letter}, which stands at its target {data.target[i]:g} "
                    f"({bad.size} such row(s); the column is not read there): a run of another axis "
                    f"labelled {letter}?")
    return None


#: angles read in degrees that are whole degrees within this (deg) once taken as radians
RADIAN_TOL_DEG = 0.01


def _radian_angles(data) -> str | None:
    """The sentence when a rotary column of a file with commanded poses (``a_deg``, ``b_deg``,
    ``c_deg``) holds at least 3 distinct angles, all within one turn in radians (|a| <= 2 pi), that
    are whole degrees only once read as radians (within :data:`RADIAN_TOL_DEG`) and, as written,
    not all multiples of 0.1 deg: angles in radians under ``*_deg``; else None (a note)."""
    names = [c for c in getattr(data, "rotary_columns", ()) if c in _ABC]
    found = []
    for col in names:
        written = np.unique(data.abc[:, _ABC.index(col)] * 180.0 / np.pi)
        written = written[np.isfinite(written)]
        if written.size < 3 or np.abs(written).max() > 2.0 * np.pi + 1e-9:
            continue
        as_radians = np.degrees(written)
        whole = np.all(np.abs(as_radians - np.round(as_radians)) < RADIAN_TOL_DEG)
        tenths = np.all(np.abs(written * 10.0 - np.round(written * 10.0)) < 1e-6)
        if whole and not tenths:
            found.append(f"{col} ({written.min():.5g} to {written.max():.5g})")
    if not found:
        return None
    return (f"{data.path}: the angles of {', '.join(found)} are whole degrees only if read as "
            "radians: angles in radians? *_deg columns are read in degrees; multiply radians by "
            "180/pi")


def _rotary_at_zero(machine, data) -> str | None:
    """The sentence when a file with commanded poses has no column for one of the machine's rotary
    axes: that axis is taken at 0 in every row (docs/measurements.md); else None."""
    if not hasattr(data, "rotary_columns") or not hasattr(data, "abc"):
        return None
    missing = [a.name for a in machine.axes
               if a.is_rotary and f"{a.name.lower()}_deg" not in data.rotary_columns]
    if not missing or not any(f"{c.lower()}_deg" in data.rotary_columns for c in "ABC"):
        return None
    cols = ", ".join(f"{a.lower()}_deg" for a in missing)
    return (f"{data.path}: no column {cols}: {' and '.join(missing)} taken at 0 in every row; "
            f"give {cols} if the table stood elsewhere")


#: the least number of deviations for the short-span unit check of a points or cmm file
POINTS_UNIT_CHECK_MIN = 10


def _mm_under_um(data, header) -> str | None:
    """The sentence when a points or cmm file's deviations look like mm written under ``*_um``
    (:func:`mtcomp.measurement.units.unit_check` over the axis whose positions span the most, the
    rule the laser files' ISO 230-2 evaluation uses), else None."""
    cols = [c for c in _DEVIATIONS if c in header]
    if data.kind not in ("points", "cmm") or not cols or not len(data.xyz):
        return None
    values = np.concatenate([np.ravel(getattr(data, "deviation", np.empty(0))),
                             np.ravel(data.normal_deviation)])
    values = values[np.isfinite(values)]
    xyz = data.xyz[np.all(np.isfinite(data.xyz), axis=1)]
    if not values.size or not len(xyz):
        return None
    along = xyz[:, int(np.argmax(np.ptp(xyz, axis=0)))]
    span = float(np.ptp(along))
    biggest = float(np.abs(values).max()) / UM
    if not unit_check(False, along, values):
        # over a short span the laser's rule says nothing; but no CMM or tracker reads every point
        # of a part within UNIT_CHECK_FLOOR_UM (its probing noise alone is more): a whole file in
        # inches (positions and deviations) spans a short distance with tiny deviations
        if values.size < POINTS_UNIT_CHECK_MIN or biggest >= UNIT_CHECK_FLOOR_UM:
            return None
        return (f"{data.path}: every deviation ({', '.join(cols)}) is below {UNIT_CHECK_FLOOR_UM:g} "
                f"um in magnitude (largest {biggest:.3g} um), less than a CMM's or a tracker's noise, "
                f"over positions spanning {span:g} mm: were the file's values written in inches or "
                "mm? positions go in mm (x_mm ...) and deviations in um (dx_um ...)")
    return (f"{data.path}: every deviation ({', '.join(cols)}) is below {unit_limit_um(span):.2g} um "
            f"in magnitude (largest {biggest:.3g} um) over positions spanning "
            f"{span:g} mm, less than a machine's errors and an instrument's noise there: were the "
            "values written in mm under *_um columns? if so multiply them by 1000")
