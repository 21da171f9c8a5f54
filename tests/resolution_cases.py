"""Cases on the independent machine (tests/truth) in which diagnose's resolution is the limit: rotary
error motions of several harmonics, seed 003 through the generic path, a screw period beside a
backlash, feed-dependent Abbe errors. Shared by tests/test_diagnose_resolution_truth.py and
benchmarks/bench_diagnose_resolution.py."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from truth import profiles as P
from truth.effects import ROTARY_COMPONENTS, UM, URAD, Backlash, Effect, PeriodicError
from truth.hidden import hidden_case


@dataclass(frozen=True)
class RotaryHarmonics(Effect):
    """Error motions of rotary ``axis`` (radial pair, axial, tilt pair) with harmonics ``orders`` of
    the angle: each component a :func:`truth.profiles.random_fourier` of ``radial_um`` /
    ``axial_um`` / ``tilt_urad`` drawn from ``seed``."""

    axis: str
    orders: tuple = (2, 3, 4)
    radial_um: float = 3.0
    axial_um: float = 1.5
    tilt_urad: float = 6.0
    seed: int = 0
    name = "rotary_pdge"

    def profiles(self) -> dict:
        rng = np.random.default_rng(self.seed)
        axial, radial, tilt = ROTARY_COMPONENTS[self.axis]
        out = {axial: P.random_fourier(rng, self.axial_um * UM, 0.0, self.orders)}
        for c in radial:
            out[c] = P.random_fourier(rng, self.radial_um * UM, 0.0, self.orders)
        for c in tilt:
            out[c] = P.random_fourier(rng, self.tilt_urad * URAD, 0.0, self.orders)
        return out

    def component_delta(self, machine, axis, s, ctx, base):
        if axis != self.axis:
            return {}
        return {c: f(s) for c, f in self.profiles().items()}


@dataclass(frozen=True)
class Together(Effect):
    """Several effects of one ``axis`` at once (their component deltas add)."""

    axis: str
    effects: tuple = ()
    name = "periodic_error"

    def component_delta(self, machine, axis, s, ctx, base):
        out: dict = {}
        for e in self.effects:
            for c, v in e.component_delta(machine, axis, s, ctx, base).items():
                out[c] = out.get(c, 0.0) + v
        return out


def pdge_case(seed: int, folder, orders=(2, 3, 4)):
    """A CAFXYZ machine whose C axis has error motions of harmonics ``orders``, seen by ball-bar
    circles at two feeds and the three-sphere set-up (noise 0.3 um)."""
    eff = RotaryHarmonics("C", tuple(orders), seed=1000 + seed)
    return hidden_case(seed, "rotary_pdge", "ballbar", "cafxyz", folder, hidden=eff)


def periodic_backlash_case(seed: int, folder, period_mm: float = 20.0):
    """Laser runs of X on an XFYZ machine with a ``period_mm`` screw period (1.5 um) and a backlash
    (5 um) of X."""
    eff = Together("X", (PeriodicError("X", period_mm, 1.5, 0.3 + seed), Backlash("X", 5.0)))
    return hidden_case(seed, "periodic_error", "laser", "xfyz", folder, hidden=eff)


#: feed-dependent Abbe cases (seed, kind, topology) of the truth benchmark
ABBE_CASES = ((9004, "laser", "xfyz"), (9012, "mixture", "cafxyz"), (9020, "rich", "cbfxyz"))


def abbe_case(k: int, folder):
    seed, kind, topo = ABBE_CASES[k % len(ABBE_CASES)]
    return hidden_case(seed + 1000 * (k // len(ABBE_CASES)), "feed_dependent_abbe", kind, topo, folder)


def seed003_diagnosed(seed: int, folder):
    """(Diagnosis, (72,) um): seed 003's three-sphere file of an independent machine diagnosed on the
    built-in CAFXYZ machine (no error motions declared: diagnose must find them), and the distance
    between the model's and the truth's C-axis points at the table face and 100 mm above it."""
    from independent_cases import seed003_case, seed003_errors_um
    from mtcomp.diagnose import diagnose
    from mtcomp.machine import load_machine
    from mtcomp.measurement.files import read_measurements
    truth, path, _ = seed003_case(seed, folder)
    d = diagnose(load_machine("cafxyz"), [read_measurements(path)])
    return d, seed003_errors_um(d.model, truth)
