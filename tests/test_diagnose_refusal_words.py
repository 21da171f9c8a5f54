"""The words of a refused feed-dependent Abbe candidate (docs/diagnose.md, "Refused"): a gain or a
moving centre of an angle the model holds at zero (a pitch no file measured) has a column of
round-off, and its fitted value is round-off over round-off. It was printed as "AG_BX would grow by
6.42e+27 % of itself"; it is "not determined". A gain fitted on a real column keeps the ratio."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from mtcomp import load_machine
from mtcomp.diagnose._candidates import Candidate
from mtcomp.diagnose._refusal import absurd


def _stack(n=6):
    feed = np.array([1000.0, 3000.0, 5000.0] * (n // 3))
    return SimpleNamespace(feed=feed, machine=load_machine("xfyz"), unit=np.array(["um"] * n),
                           y=np.linspace(-0.005, 0.005, n))


def _candidate(ag_column):
    n = len(ag_column)
    af = np.linspace(1.0, 74.0, n)                      # the constant part's column (as the user's)
    return Candidate("feed_dependent_abbe", "X", "gain+constant:AG_BX", np.column_stack([ag_column, af]),
                     [], ["AG_BX", "AF_BX"])


def test_a_gain_of_an_angle_held_at_zero_is_not_determined():
    st = _stack()
    # the user's numbers: a column of 2e-26 mm per unit gain, a gain of 1.28e25 per m/min
    c = _candidate(np.full(6, 2.0e-26))
    why = absurd(st, c, np.array([1.2834e25, -1.0786e-6]))
    assert why is not None and why.startswith("AG_BX is not determined: it acts through EBX"), why
    assert "%" not in why


def test_a_gain_on_a_measured_angle_keeps_its_ratio():
    st = _stack()
    c = _candidate(np.linspace(0.1, 50.0, 6))
    # a gain of 1 per m/min at 5 m/min: the angle grows by 5 times itself, 500 %, above 3 times
    why = absurd(st, c, np.array([1.0, 0.0]))
    assert why == "its angular error (AG_BX) would grow by 500 % of itself at 5000 mm/min", why
