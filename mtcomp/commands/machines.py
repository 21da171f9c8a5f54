"""`mtcomp machines`: list the built-in machines."""
from __future__ import annotations

from ..machine import builtin_machine_summaries


def add_arguments(parser):
    pass


def run(args) -> int:
    print("built-in machines (name, topology, description, travel):")
    for line in builtin_machine_summaries():
        print("  " + line)
    print("A machine can also be given as a TOML file (format: docs/machines.md).")
    return 0
