"""Where the tests find real measured data.

* The 46 h spindle thermal record (MIT licence) is in the repository: tests/data/real/thermal, with
  its licence and source (SOURCES.md there). Tests that use it always run.
* The ISO 230-2 runs of real stages carry no licence or the GPL: they are read from the project's
  shared data folder beside the repository (``../shared/data/real``); tests that need them skip,
  saying so, when it is absent.
"""
from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the real spindle thermal record, in the repository
THERMAL = ROOT / "tests" / "data" / "real" / "thermal" / "fl_thermal.csv"
#: the shared real data: $MTCOMP_REAL_DATA, else the folder beside the repository (absent on a
#: plain clone); the benchmarks look in the same places
SHARED_REAL = (Path(os.environ["MTCOMP_REAL_DATA"]) if os.environ.get("MTCOMP_REAL_DATA")
               else ROOT.parent / "shared" / "data" / "real")
ISO230_2 = SHARED_REAL / "iso230_2"
