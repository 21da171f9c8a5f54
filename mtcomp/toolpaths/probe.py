"""BeagleG's G30, a Z probe (docs/toolpaths.md, "BeagleG").

BeagleG's ``G30 [Z<thickness>] [F<feed>]`` (its G-code.md, "G Codes"; src/gcode-parser/gcode-parser.cc,
``handle_z_probe``) moves Z until its probe switch triggers and then sets the G92 offset of Z so that
the tool reads the thickness there (0 without a Z word): the probed height, so Z's machine position
and that offset, are not in the program. The words after the G30 that are not its own (its F and Z
read as pairs until the first other word) act as usual: ``G30 G1 Z0`` probes, then moves to Z0 of
the new offset.

mtcomp follows it as it follows a move whose start is not known and whose end the program gives:
Z is unknown after the probe, the line passes through as written, uncorrected, and where a move
after the G30 names Z it stands there at its written value, in the program and in the output alike
(:func:`.passed.passed_end`: the probe sets the same offset in both, at the height where the tool
touched). The Z positions after it are placed on the machine with that G92 offset taken as 0, as an
unstated work offset, and the notes say so once.
"""
from __future__ import annotations

from .passed import passed_end

__all__ = ["beagleg_probe", "passed_probe"]

#: the letters BeagleG's handle_z_probe reads as the G30's own words
_PROBE_WORDS = "FZ"


def beagleg_probe(state, tokens, values: dict, gcodes: list, line: int) -> None:
    """A G30 of a BeagleG line (``gcodes`` holds 30): the probe's own words taken out of ``values``
    and the G30 out of ``gcodes`` (in place), Z unknown from here, ``state.probe_line`` set to the
    line (:func:`passed_probe` then passes it through). Refused where it does not stand first among
    the line's G codes after a dwell (the words before it would act before the probe) or where a
    G52/G92 offset is in force (the probe replaces the G92 offset of Z)."""
    words = [(letter, raw) for letter, _num, raw in tokens if letter not in "(;"]
    at = next(k for k, (letter, raw) in enumerate(words)
              if letter == "G" and float(raw[1:]) == 30)
    before = [raw for letter, raw in words[:at] if letter not in "GPN"]
    if before:
        raise state._err(f"{before[0]} before G30 (BeagleG's Z probe) on one line: put the probe "
                         "first", line)
    if state.shift_by or not state.local.identity:
        raise state._err("G30 (BeagleG's Z probe, which sets the G92 offset of Z) while a G52 or "
                         "G92 offset is in force is not supported", line)
    own = []
    for letter, _raw in words[at + 1:]:
        if letter not in _PROBE_WORDS or letter in own:
            break
        own.append(letter)
    for letter in own:
        values.pop(letter)
    gcodes[:] = [g for g in gcodes if g != 30]
    zi = state.xyz_index[2]
    if zi >= 0:
        state.known[zi] = False
        state.dirs[zi] = 0
    state.probe_line = line
    _note_probe(state, line)


def passed_probe(state, values: dict, axes_given, motion, line: int) -> None:
    """The line of a BeagleG G30: passed through as written; the axes a move after the probe names
    stand at their written values after it (G90; in G91 they move by their increments). An arc
    after the probe on its line is refused (its start, where the probe stopped, is not known)."""
    if motion is not None:
        if motion in (2, 3):
            raise state._err(f"G30 (BeagleG's Z probe) and an arc G{motion} on one line: put the "
                             "arc on a line of its own", line)
        state.motion = motion
    passed_end(state, values, axes_given, "probe", line)
    state.probe_line = None


def _note_probe(state, line: int) -> None:
    """Say once, in the program's notes, how the Z positions after a probe are placed."""
    notes = getattr(state._source, "notes", None)
    if notes is None:
        return
    note = (f"assumed: G30 at line {state._where(line)[1]} (BeagleG's Z probe) sets the G92 offset "
            "of Z from the probed height, which the program does not give: Z is not written until "
            "the program names it, and its positions after that are placed with that offset = 0 "
            "(as an unstated work offset); where the probed height is known, add it to "
            "--work-offset")
    if not any("(BeagleG's Z probe)" in n for n in notes):
        notes.append(note)
