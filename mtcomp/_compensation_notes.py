"""The notes a compensation prints after its run (one line each): moves passed through uncorrected,
axis words added, tool centre point mode, the program's expansion, cutter radius compensation,
arcs, drilling cycles, datums outside the data, feeds and the set-up's assumptions."""
from __future__ import annotations

import numpy as np

from .toolpaths.haas5 import mrzp_text


#: the moves the writer passes through uncorrected (``passed_moves`` of its stats), in this order
_PASSED_MOVES = {"increment": "{n} incremental (G91) move{s} of an axis whose position the program "
                              "has not given ({at}: the controller moves it from wherever it stands)",
                 "home": "{n} move{s} to the home position (G28/G30, grbl's $H; {at})",
                 "jog": "{n} grbl jog{s} ($J=, {at})",
                 "arc": "{n} arc{s} from a position the program has not given ({at}: the controller "
                        "runs it from wherever the machine stands; its end is known after it)",
                 "spline": "{n} spline{s} (G5, G5.1; {at}: its control points are not corrected, "
                           "its end is known after it)",
                 "machine": "{n} move{s} in machine coordinates (G53, {at})",
                 "height map": "{n} height map probing{s} (uCNC's G39, {at}: Z stands where the "
                               "grid's first point was probed; X Y as the line names them)",
                 "probe": "{n} Z probe{s} (BeagleG's G30, {at}: Z stands where the probe stopped; "
                          "a move after it on its line passes as written, its end known)",
                 "single": "{n} single-direction positioning{s} (Fanuc G60, {at}: its end is "
                           "known, the axes' approach direction is the control's parameter's)",
                 "tap": "{n} rigid tapping move{s} (G33.1, {at}: the spindle's reversal sets its ends)",
                 "restore": "{n} move{s} to a RepRapFirmware restore point (G0/G1 R, {at}: the "
                            "controller saved it)",
                 "controller": "{n} move{s} to a value the controller holds or under a tool "
                               "length it holds ({at}: its position, a probe's result, a setting; "
                               "an axis given such a value is not written until positioned again)",
                 "probing": "{n} probing move{s} (G38.2-G38.5, {at}: the axes named stand where "
                            "the probe stopped, not written until positioned again)",
                 "subprogram": "{n} call{s} of a subprogram not in the file ({at}: its moves are "
                               "not seen)"}


def passed_move_notes(program, written) -> list[str]:
    """The line counting the motion lines passed through uncorrected that are no block of the plan
    (so no BLOCKS.csv row), by why, each with its (first) source line; none when there are none."""
    passed = written.get("passed_moves") or {}
    parts = []
    for why, text in _PASSED_MOVES.items():
        if why in passed:
            n, line = passed[why]
            at = int(program.source_lines_of([line])[0])
            parts.append(text.format(n=n, s="" if n == 1 else "s",
                                     at=f"{'first at ' if n > 1 else ''}line {at}"))
    total = sum(n for n, _line in passed.values())
    if not total:
        return []
    return [f"{total} motion line{'' if total == 1 else 's'} passed through uncorrected, with no "
            f"BLOCKS.csv row: " + "; ".join(parts)]


def added_words_note(program, written) -> list[str]:
    """The line counting the motion lines written with axis words they did not name, and why
    (the writer's count ``added_axis_words``: lines and the first line, which this puts in the
    user's file's numbering)."""
    n, line = written.get("added_axis_words") or (0, 0)
    if not n:
        return []
    at = int(program.source_lines_of([line])[0])
    written["added_axis_words"] = (n, at)       # the line of the user's file (SUMMARY.json too)
    return [f"{n} line{'' if n == 1 else 's'} written with axis words {'it' if n == 1 else 'they'} "
            f"did not name ({'first at ' if n > 1 else ''}line {at}): the correction of that axis "
            "changes there (its error varies with the other axes' positions, or the step bound "
            "ramps a correction in or out), and the controller keeps what a line does not say "
            "(an axis where it stood, a drilling cycle's depth); never an axis whose position "
            "the program has not given, nor a rotary axis the program holds (outside tool centre "
            "point mode)"]


def tcp_note(program, tally) -> list[str]:
    """The line saying how many blocks were compensated in tool centre point mode and which code
    switched it on at which source line (as the reader recorded it: the last switch on the lines
    up to each run's first block)."""
    if not tally.tcp_blocks:
        return []
    switches = []
    recorded = sorted((k, c) for k, c in getattr(program, "tcp_switches", {}).items()
                      if c != "G254")
    if getattr(program, "sinumerik", None) is not None:      # read as M428 (docs/toolpaths.md)
        recorded = [(line, "TRAORI") for line, _code in recorded]
    for before, first in tally.tcp_runs[:3]:
        last = [(line, code) for line, code in recorded if line <= first]
        if last and last[-1][0] > before:
            line, code = last[-1]
            switches.append(f"{code} at line {int(program.source_lines_of([line])[0])}")
    n = tally.tcp_blocks
    said = ", ".join(switches) + (", ..." if len(tally.tcp_runs) > 3 else "")
    return [f"{n} block{'' if n == 1 else 's'} in tool centre point mode"
            + (f" ({said})" if said else "") + ": tip positions and tool angles in the workpiece "
            "frame, compensated there and written so; the controller solves the kinematics"]


def haas_note(program, tally, machine) -> list[str]:
    """The line naming Haas' G234 and G254 blocks and the machine rotary zero point (MRZP) they
    were placed by: the machine file's rotary axis lines."""
    codes = set(getattr(program, "tcp_switches", {}).values())
    if not ({"G234", "G254"} & codes and (tally.tcp_blocks or tally.dwo_blocks)):
        return []
    n = tally.dwo_blocks
    dwo = (f"{n} block{'' if n == 1 else 's'} under G254 (first at line "
           f"{int(program.source_lines_of([tally.dwo_line])[0])}): X Y Z along the machine's axes "
           "from the part origin (the work offset) turned with the table; " if n else "")
    return [f"Haas 5-axis modes: {dwo}the machine rotary zero point (MRZP, Haas settings 255-257) "
            f"is taken as the machine file's rotary axis lines: {mrzp_text(machine)}; it must be "
            "the control's"]


def _run_notes(program, written, fitted, setup, tally, found, datum=()) -> list[str]:
    """The notes after a run: moves passed through, tool centre point mode, the program's
    expansion, drilling cycles, datums (``datum``: :func:`datum_notes`'s notes), feeds, set-up."""
    notes = passed_move_notes(program, written) + added_words_note(program, written) \
        + tcp_note(program, tally) + haas_note(program, tally, setup.machine) + list(program.notes)
    if written.get("unchanged"):
        notes.append("note: no block of the program can be corrected (it moves no axis, or only "
                     "from positions it does not give): it is written unchanged, byte for byte")
    elif program.expanded:
        notes.append(f"the program's code was run: {program.executed} lines executed from its "
                     f"{program.source_lines}; the output is that expansion, corrected (a comment "
                     "at its top says so)")
    # found in the user's file (an expansion is gone by now)
    if b"41" in found or b"42" in found:
        miss = written.get("cutter_arc_miss_mm", 0.0) * 1e3
        crc = "RL/RR" if program.heidenhain is not None else "G41/G42"
        notes.append(f"note: the program uses cutter radius compensation ({crc}): the corrections "
                     "are those of the programmed contour, while the tool centre runs a radius off "
                     "it (the error there differs by the model's change over that distance); no "
                     "block is split (the controller offsets the moves as written)"
                     + (f", and an arc under it is kept whole: the written arcs miss their "
                        f"corrected path by up to {miss:.2f} um" if miss >= 0.005 else ""))
    arc = written.get("arc_miss_mm", 0.0) * 1e3
    if arc >= 0.005:
        notes.append(f"note: the arcs written miss their corrected path by up to {arc:.2f} um (within "
                     "--chord-tol-um): the predicted deviation after is that of the corrected path")
    return notes + _cycle_notes(written) + list(datum) + tally.feed_note(fitted) \
        + setup.notes()


def _cycle_notes(written: dict) -> list[str]:
    def cycle_lines(k):
        return f"{k} drilling cycle line{'' if k == 1 else 's'} (G73, G81-G89)"
    notes = []
    if written.get("cycle_blocks"):
        notes.append(f"{cycle_lines(written['cycle_blocks'])} kept as cycles, each hole corrected "
                     "where the model applies and the bounds let it (X Y Z to the hole's bottom, R "
                     "moved with Z; BLOCKS.csv says which)")
    if written.get("cycle_lines"):
        notes.append(f"{cycle_lines(written['cycle_lines'])} passed through unchanged and "
                     "uncorrected: hole position, R or Z not known, drilling along another "
                     "axis than Z, or a rotary axis word in their series of cycles")
    return notes


def datum_notes(fitted, setup, gated=None) -> tuple[list[str], list[str]]:
    """One line for each part's datum (the origin of a work offset the program used) outside the
    region the model's data reached: the corrections are referenced to the model's deviation there,
    its continuation beyond the data. ``gated``: datum (machine positions, a tuple) -> [blocks,
    first line of the user's file] left uncorrected for it (the planner's ``DatumRule.gated``):
    the line counts them and says what to do. Returns (the notes, the lines of blocks left
    uncorrected: the summary's, among its other reasons)."""
    from .models.region import support_bounds
    from .toolpaths.offsets import WORK_SYSTEMS
    bounds = support_bounds(fitted)
    left = dict(gated or {})
    out = []
    for w in sorted(setup.used_wcs):
        datum = np.asarray(setup._offset_table()[w], dtype=float)
        hit = [k for k in left if np.allclose(k, datum, rtol=0, atol=1e-9)]
        out += _datum_line(fitted.machine, bounds, f"the part's datum of {WORK_SYSTEMS[w]}", datum,
                           left.pop(hit[0]) if hit else None)
    # a datum no work offset of the set-up names (one the program set itself, G10)
    for k, v in left.items():
        out += _datum_line(fitted.machine, bounds, "the part's datum", np.asarray(k), v)
    return [t for t in out if t.startswith("note:")], [t for t in out if not t.startswith("note:")]


def _datum_line(machine, bounds, name, datum, hit) -> list[str]:
    """:func:`datum_notes`'s line of one datum (machine positions) ``name``d; ``hit``: [blocks,
    first line] left uncorrected for it, or None."""
    from .models.region import outside_bounds
    outside = outside_bounds(machine, bounds, datum[None, :])[0]
    off = [j for j, o in enumerate(outside) if o]
    if not off:
        return []
    where = ", ".join(f"{machine.axis_names[j]} {_value(machine, j, datum[j]):g}" for j in off)
    if hit is None:
        return [f"note: {name} ({where}) lies outside the region the model's data reached: the "
                "corrections are referenced to the model's deviation there, its continuation "
                "beyond the data"]
    reach = ", ".join(_reach(machine, j, bounds[0][j], bounds[1][j]) for j in off)
    k, line = hit
    return [f"{k} block{'' if k == 1 else 's'} not corrected: {name} ({where}) lies outside the "
            f"region the model's data reached ({reach}; first at line {line}): every correction "
            "is referenced to the model's deviation at the datum, which no data determine "
            "(BLOCKS.csv correction_sd_um blank, uncertain 1); measure there, set the datum inside "
            "the region, or pass --extrapolate to correct against the model's continuation there"]


def _value(machine, j, v) -> float:
    """Axis j's position ``v`` as the user reads it (deg for a rotary axis, mm)."""
    return float(np.degrees(v)) if machine.axes[j].is_rotary else float(v)


def _reach(machine, j, lo, hi) -> str:
    """'X -100 .. 100 mm', or 'A at 30 deg only' for an axis the data held at one angle."""
    unit = "deg" if machine.axes[j].is_rotary else "mm"
    lo, hi = _value(machine, j, lo), _value(machine, j, hi)
    name = machine.axis_names[j]
    return f"{name} at {lo:g} {unit} only" if hi - lo < 1e-9 else f"{name} {lo:g} .. {hi:g} {unit}"
