"""The command-line commands, one module each (``add_arguments`` and ``run``), and what they share."""
from __future__ import annotations

import sys


def note_outside_travel(command: str, machine, datasets) -> None:
    """Tell the user (stderr, one line per file and axis) of readings beyond the machine's travel."""
    from ..measurement.readings import outside_travel
    for note in outside_travel(machine, datasets):
        print(f"mtcomp {command}: note: {note}", file=sys.stderr)
