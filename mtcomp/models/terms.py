"""Error terms beyond the base model, each a symbolic extension of the chain.

A term adds parameters and acts on the chain in one or more of three places:

* ``axis_errors``: contributions to the six component errors of one axis (backlash, periodic screw
  error, feed-dependent offset, rotary error motions, angle gains);
* ``abbe_centres``: shifts of the centre about which an angular error of a linear axis turns its
  carriage (the instantaneous rotation centre of Yang et al. (2020), eqs. 2-4);
* ``tip_offset``: a translation of the tool tip in the workpiece frame (thermal drift).

Terms read block context (feed, approach directions, time, temperatures ...) from ``ctx``, a dict of
CasADi scalars keyed by context name (see :data:`mtcomp.models.chain.BASE_CONTEXT`). A term that needs
another context channel (e.g. a temperature) lists it in ``context_names``.

Each term is a small frozen dataclass that can be written to and read from MODEL.json (``to_dict`` /
:func:`term_from_dict`), so compensate and predict use an extended model directly.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import casadi as ca

from .basis import axis_spline
from .params import ParamSpec

ANGLE_LETTERS = "ABC"
TRANSLATION_LETTERS = "XYZ"


def positioning_component(axis_name: str) -> str:
    """'X' -> 'EXX', 'C' -> 'ECC': the component along (linear) or about (rotary) the axis itself."""
    return f"E{axis_name}{axis_name}"


def motion_pair(component: str) -> tuple[str, int] | None:
    """(partner, sign) when rotary error motion ``component`` leads a radial or a tilt pair (the pair's
    first direction in X, Y, Z order: EXC of EXC/EYC, EAC of EAC/EBC, EYA of EYA/EZA, EXB of EXB/EZB
    ...), None for the partner and the axial motion. The leader's first harmonic, ``<comp>_c1`` cos +
    ``<comp>_s1`` sin, is the pair's one that turns against the axis; its partner moves by
    ``sign * (<comp>_s1 cos - <comp>_c1 sin)`` (:func:`motion_errors`).

    The sign: the chain turns the axis's carriage by R(theta) about direction d (right-handed), which
    in the cyclic plane (d+1, d+2) turns (u, v) to (u cos - v sin, u sin + v cos). R(-theta)(p, q) is
    the counter-rotating motion: (p cos + q sin, q cos - p sin) when the leader is direction d+1 (C:
    X before Y, A: Y before Z), sign +1; for B the leader X is direction d+2, sign -1."""
    d = ANGLE_LETTERS.index(component[2])
    i = "XYZABC".index(component[1]) % 3
    if i == d:
        return None
    j, k = (d + 1) % 3, (d + 2) % 3
    lead, other = min(j, k), max(j, k)
    if i != lead:
        return None
    letters = TRANSLATION_LETTERS if component[1] in TRANSLATION_LETTERS else ANGLE_LETTERS
    return f"E{letters[other]}{component[2]}", (1 if lead == j else -1)


def motion_harmonics(component: str, order: int) -> range:
    """The harmonics k whose coefficients ``<component>_c<k>``, ``<component>_s<k>`` are parameters of
    rotary error motion ``component`` ('EXC', 'EZC', 'EAC' ...) up to ``order``: 1..order for the
    axial motion (along the axis) and for the leader of the radial pair and of the tilt pair
    (:func:`motion_pair`), 2..order for their partners.

    The motions are in the frame that does not turn with the axis. There an offset v of the axis line
    moves a carried point by v - R(theta) v, and a carried artefact set off centre by w moves it by
    R(theta) w: between them they span the constant and the first harmonic turning WITH the axis (the
    tilt pair likewise with the line's tilt and the artefact's). The first harmonic turning the other
    way is neither: a once-per-turn motion along X alone (EXC = e cos theta, EYC = 0) is half of each,
    and two sensitive directions measured together (R-test, three spheres, a ball bar in a plane) tell
    them apart; only a single fixed sensitive direction cannot, where ISO 230-7:2015 removes the
    whole fundamental. So each pair carries its first harmonic as the counter-rotating combination
    only, two parameters on the leader, and the partner starts at harmonic 2."""
    axial = TRANSLATION_LETTERS[ANGLE_LETTERS.index(component[2])]
    first = component[1] == axial or motion_pair(component) is not None
    return range(1 if first else 2, order + 1)


def motion_errors(component: str, order: int, s, par) -> dict:
    """{component: its Fourier series in angle ``s`` up to ``order``} from the parameters ``par(name)``
    (:func:`motion_harmonics`), plus {partner: the counter-rotating first harmonic's share} when
    ``component`` leads a pair (:func:`motion_pair`). The one place the series is written: the base
    chain and :class:`RotaryErrorMotion` both use it."""
    e = ca.SX(0)
    for k in motion_harmonics(component, order):
        e = e + par(f"{component}_c{k}") * ca.cos(k * s) + par(f"{component}_s{k}") * ca.sin(k * s)
    out = {component: e}
    pair = motion_pair(component)
    if pair is not None and order >= 1:
        partner, sign = pair
        out[partner] = sign * (par(f"{component}_s1") * ca.cos(s) - par(f"{component}_c1") * ca.sin(s))
    return out


class Term:
    """Base class: a term contributes nothing unless it overrides a hook."""

    kind = "term"

    def key(self) -> str:
        raise NotImplementedError

    def param_specs(self, machine) -> list[ParamSpec]:
        return []

    def context_names(self, machine) -> list[str]:
        return []

    def axis_errors(self, machine, axis, s, ctx, P, components) -> dict:
        """Extra component errors of ``axis`` (dict component name -> SX), given the errors so far."""
        return {}

    #: the term acts through the block's feed (a program's moves without a feed take it at 0)
    uses_feed = False

    def abbe_centres(self, machine, axis, s, ctx, P) -> dict:
        """Shift (3-vector SX, mm, carriage frame) of the centre of each angular error of a linear axis,
        keyed by 'A', 'B' or 'C' (rotation about X, Y, Z)."""
        return {}

    def tip_offset(self, machine, q, ctx, P):
        """Translation (3-vector SX, mm) of the tool tip in the workpiece frame, or None."""
        return None

    def to_dict(self) -> dict:
        return {"kind": self.kind, **asdict(self)}


@dataclass(frozen=True)
class Backlash(Term):
    """Lost motion of an axis: its positioning error steps by ``BL_<axis>`` with the approach direction.

    ``E<axis><axis> += BL/2 * dir``, so that mean(up) - mean(down) = BL, the ISO 230-2 reversal value B
    (B is mean up minus mean down). Rotary axes: the rotary backlash of Pi et al. (2017), in urad.

    ``profile=True`` (linear axes on a spline basis): the reversal varies along the axis, as a
    bidirectional pitch table holds it: ``BL(s) = BL + sum_j BL_<axis>_b<j> phi_j(s)`` with the zero-mean
    spline functions of the axis's own basis (mtcomp.models.basis), so ``BL`` stays the mean reversal.
    """

    axis: str
    profile: bool = False
    kind = "backlash"

    def key(self):
        return f"backlash:{self.axis}"

    def _profile_terms(self, machine) -> list[int]:
        ax = machine.axis(self.axis)
        if not self.profile:
            return []
        if ax.is_rotary or ax.basis != "bspline":
            raise ValueError(f"a backlash profile needs a linear axis on a spline basis ({self.axis})")
        return axis_spline(ax).kept(False)

    def param_specs(self, machine):
        rotary = machine.axis(self.axis).is_rotary
        unit = "urad" if rotary else "um"
        specs = [ParamSpec(f"BL_{self.axis}", unit, self.key(), False,
                           f"reversal (backlash) of {self.axis}: mean up minus mean down")]
        for j in self._profile_terms(machine):
            specs.append(ParamSpec(f"BL_{self.axis}_b{j}", unit, self.key(), False,
                                   f"reversal of {self.axis} along the axis: B-spline coefficient {j}"))
        return specs

    def axis_errors(self, machine, axis, s, ctx, P, components):
        if axis.name != self.axis:
            return {}
        reversal = P[f"BL_{self.axis}"]
        terms = self._profile_terms(machine)
        if terms:
            for j, phi in zip(terms, axis_spline(axis).functions(s, False)):
                reversal = reversal + P[f"BL_{self.axis}_b{j}"] * phi
        return {positioning_component(self.axis): 0.5 * reversal * ctx[f"dir_{self.axis}"]}


@dataclass(frozen=True)
class PeriodicError(Term):
    """Cyclic positioning error of a linear axis (ball-screw lead, scale period).

    ``E<axis><axis> += PER_<axis>_c cos(2 pi s / period) + PER_<axis>_s sin(2 pi s / period)``.
    """

    axis: str
    period_mm: float
    kind = "periodic_error"

    def key(self):
        return f"periodic_error:{self.axis}"

    def param_specs(self, machine):
        return [ParamSpec(f"PER_{self.axis}_c", "um", self.key(), False,
                          f"cosine amplitude of the {self.period_mm:g} mm cyclic error of {self.axis}"),
                ParamSpec(f"PER_{self.axis}_s", "um", self.key(), False,
                          f"sine amplitude of the {self.period_mm:g} mm cyclic error of {self.axis}")]

    def axis_errors(self, machine, axis, s, ctx, P, components):
        if axis.name != self.axis:
            return {}
        w = 2.0 * math.pi / self.period_mm
        return {positioning_component(self.axis):
                P[f"PER_{self.axis}_c"] * ca.cos(w * s) + P[f"PER_{self.axis}_s"] * ca.sin(w * s)}


@dataclass(frozen=True)
class FeedOffset(Term):
    """A positioning error proportional to feed, uniform along the axis (a dynamic lag of the reading).

    ``E<axis><axis> += FOFF_<axis> * feed`` with feed in m/min; with ``signed`` the offset follows the
    approach direction (a lag behind the motion): ``... * dir``.
    """

    axis: str
    signed: bool = False
    kind = "feed_dependent_offset"
    uses_feed = True

    def key(self):
        return f"feed_dependent_offset:{self.axis}"

    def param_specs(self, machine):
        return [ParamSpec(f"FOFF_{self.axis}", "um", self.key(), False,
                          f"positioning offset of {self.axis} per m/min of feed")]

    def axis_errors(self, machine, axis, s, ctx, P, components):
        if axis.name != self.axis:
            return {}
        e = P[f"FOFF_{self.axis}"] * ctx["feed"] / 1000.0
        if self.signed:
            e = e * ctx[f"dir_{self.axis}"]
        return {positioning_component(self.axis): e}


@dataclass(frozen=True)
class AbbeIRC(Term):
    """Abbe errors about the instantaneous rotation centre (IRC) of a linear axis (Yang et al. (2020),
    eqs. 2-4).

    The base model turns each carriage about its reference point (the nominal Abbe arm). Yang et al.
    (2020) show that the worktable turns about a centre that moves with position and feed. For each
    angular error ``E<a><axis>`` (a in ``angles``), the centre is shifted, in the two coordinates
    perpendicular to the rotation, by

        o = IRC_<a><axis>_<c>0 + IRC_<a><axis>_<c>_s * s/(1 m) + IRC_<a><axis>_<c>_f * feed/(1 m/min)

    (mm; ``static``, ``position`` and ``feed`` choose which parts exist), and with ``angle_gain`` the
    angle itself scales with feed: ``E<a><axis> *= 1 + AG_<a><axis> * feed/(1 m/min)``. The base model
    holds no constant part of an angular error (set-ups take it), so an angle that scales as a whole
    also needs ``angle_feed``: ``E<a><axis> += AF_<a><axis> * feed/(1 m/min)`` (rad), the constant
    part times its gain, the same all along the axis.

    Yang et al. (2020), eq. (3), give the yaw Abbe error about O_p as (-eps_z * Y', eps_z * X', 0),
    i.e. the small-angle form of the exact rotation used here; eq. (4)'s last row prints
    ``eps * Y_B3`` where ``eps_x * Y_B3`` is meant (roll about X).
    """

    axis: str
    angles: str = "ABC"
    static: bool = False
    position: bool = False
    feed: bool = True
    angle_gain: bool = False
    angle_feed: bool = False
    kind = "abbe_irc"

    @property
    def uses_feed(self) -> bool:
        return bool(self.feed or self.angle_gain or self.angle_feed)

    def key(self):
        return f"abbe_irc:{self.axis}"

    def _coords(self, a):
        i = ANGLE_LETTERS.index(a)
        return [TRANSLATION_LETTERS[j] for j in range(3) if j != i]

    def param_specs(self, machine):
        specs = []
        for a in self.angles:
            for c in self._coords(a):
                base = f"IRC_{a}{self.axis}_{c.lower()}"
                if self.static:
                    specs.append(ParamSpec(base + "0", "mm", self.key(), False,
                                           f"{c} of the E{a}{self.axis} rotation centre"))
                if self.position:
                    specs.append(ParamSpec(base + "_s", "mm", self.key(), False,
                                           f"{c} shift of the E{a}{self.axis} centre per m of travel"))
                if self.feed:
                    specs.append(ParamSpec(base + "_f", "mm", self.key(), False,
                                           f"{c} shift of the E{a}{self.axis} centre per m/min of feed"))
            if self.angle_gain:
                specs.append(ParamSpec(f"AG_{a}{self.axis}", "1", self.key(), False,
                                       f"relative gain of E{a}{self.axis} per m/min of feed"))
            if self.angle_feed:
                specs.append(ParamSpec(f"AF_{a}{self.axis}", "urad", self.key(), False,
                                       f"E{a}{self.axis} added uniformly along the axis per m/min of feed"))
        return specs

    def abbe_centres(self, machine, axis, s, ctx, P):
        if axis.name != self.axis:
            return {}
        out = {}
        for a in self.angles:
            o = [ca.SX(0), ca.SX(0), ca.SX(0)]
            for c in self._coords(a):
                base = f"IRC_{a}{self.axis}_{c.lower()}"
                j = TRANSLATION_LETTERS.index(c)
                if self.static:
                    o[j] = o[j] + P[base + "0"]
                if self.position:
                    o[j] = o[j] + P[base + "_s"] * s / 1000.0
                if self.feed:
                    o[j] = o[j] + P[base + "_f"] * ctx["feed"] / 1000.0
            out[a] = ca.vertcat(*o)
        return out

    def axis_errors(self, machine, axis, s, ctx, P, components):
        if axis.name != self.axis or not (self.angle_gain or self.angle_feed):
            return {}
        out = {}
        for a in self.angles:
            comp = f"E{a}{self.axis}"
            v = ca.SX(0)
            if self.angle_gain:
                v = v + components[comp] * P[f"AG_{a}{self.axis}"] * ctx["feed"] / 1000.0
            if self.angle_feed:
                v = v + P[f"AF_{a}{self.axis}"] * ctx["feed"] / 1000.0
            out[comp] = v
        return out


@dataclass(frozen=True)
class RotaryErrorMotion(Term):
    """Error motion of a rotary axis beyond its location errors (Tan et al. (2026)): radial, axial and
    tilt motions as a Fourier series of the angle without constant term (the constant is a location
    error). ``component`` is the ISO 230-1 name, e.g. 'EXC', 'EYC' (radial), 'EZC' (axial), 'EAC',
    'EBC' (tilt); parameters ``<component>_c<k>``, ``<component>_s<k>`` for k in
    :func:`motion_harmonics`. The first harmonic of a radial or tilt pair is carried by its leader
    (EXC of EXC/EYC) as the combination that turns against the axis, which moves the partner too
    (:func:`motion_errors`); the one turning with the axis is the line's location and the set-up's."""

    component: str
    order: int = 2
    kind = "rotary_pdge"

    @property
    def axis(self):
        return self.component[2]

    def key(self):
        return f"rotary_pdge:{self.component}"

    def param_specs(self, machine):
        unit = "urad" if self.component[1] in ANGLE_LETTERS else "um"
        specs = []
        for k in motion_harmonics(self.component, self.order):
            for cs in "cs":
                specs.append(ParamSpec(f"{self.component}_{cs}{k}", unit, self.key(), False,
                                       f"{'cosine' if cs == 'c' else 'sine'} harmonic {k} of "
                                       f"{self.component}"))
        return specs

    def axis_errors(self, machine, axis, s, ctx, P, components):
        if axis.name != self.axis:
            return {}
        return motion_errors(self.component, self.order, s, P.__getitem__)


@dataclass(frozen=True)
class ThermalDrift(Term):
    """Thermal drift of the tool tip, linear in named drivers (ISO 230-3 style).

    ``features`` are context channels computed from the data before the fit (e.g. ``time_h``,
    ``dtemp_t1`` as a rise above its first reading, ``temp_t1`` the temperature itself in degC,
    ``spindle_heat_1800``: spindle speed filtered with a 1800 s time constant). The tip moves in the
    workpiece frame by ``sum_f TD_<dir>_<f> * feature_f`` for each direction in ``directions``.
    ``driver`` is 'time', 'temperature' or 'spindle' (what the report names).

    ``absolute``: the drift is a function of the features alone, ``TD_<dir>_zero + sum_f ...``, not a
    change since a file's first reading (docs/thermal.md): what compensation needs, since a program
    has no "first reading". ``channels``: the thermal-file channels that read the tip along each of
    ``directions`` (same order; empty: channels named x, y, z).
    """

    driver: str
    features: tuple[str, ...]
    directions: str = "XYZ"
    absolute: bool = False
    channels: tuple[str, ...] = ()
    kind = "thermal_drift"

    def key(self):
        return f"thermal_drift:{self.driver}"

    def param_specs(self, machine):
        specs = [ParamSpec(f"TD_{d}_{f}", "um", self.key(), False,
                           f"tip drift along {d} per unit of {f}")
                 for d in self.directions for f in self.features]
        if self.absolute:
            specs += [ParamSpec(f"TD_{d}_zero", "um", self.key(), False,
                                f"tip drift along {d} with every feature at zero") for d in self.directions]
        return specs

    def context_names(self, machine):
        return list(self.features)

    def channel_directions(self) -> dict:
        """Thermal channel name -> tip direction index (0, 1, 2) it reads."""
        if self.channels:
            return {ch: TRANSLATION_LETTERS.index(d) for ch, d in zip(self.channels, self.directions)}
        return {d.lower(): TRANSLATION_LETTERS.index(d) for d in self.directions}

    def tip_offset(self, machine, q, ctx, P):
        out = [ca.SX(0), ca.SX(0), ca.SX(0)]
        for d in self.directions:
            j = TRANSLATION_LETTERS.index(d)
            for f in self.features:
                out[j] = out[j] + P[f"TD_{d}_{f}"] * ctx[f]
            if self.absolute:
                out[j] = out[j] + P[f"TD_{d}_zero"]
        return ca.vertcat(*out)

    def to_dict(self):
        d = super().to_dict()
        d["features"] = list(self.features)
        d["channels"] = list(self.channels)
        return d


@dataclass(frozen=True)
class ChannelDrift(Term):
    """Drift of the named displacement channels of thermal files (docs/measurements.md), linear in drivers.

    For channels that are not tool-tip directions (a thermal file's ``disp_ch1_um`` ...), each channel
    drifts by ``sum_f TD_<channel>_<f> * feature_f`` (um per unit of feature, see
    :func:`mtcomp.measurement.drift.thermal_features` for the features); with ``absolute``
    the reading is ``TD_<channel>_zero + sum_f ...`` (see :class:`ThermalDrift`), else its change since
    the file's first reading. The term does not act on the tool tip (channels that read the tip: use
    :class:`ThermalDrift`); only the thermal measurement model reads its parameters.
    """

    driver: str
    features: tuple[str, ...]
    channels: tuple[str, ...]
    absolute: bool = False
    kind = "channel_drift"

    def key(self):
        return f"channel_drift:{self.driver}"

    def param_specs(self, machine):
        specs = [ParamSpec(f"TD_{ch}_{f}", "um", self.key(), False,
                           f"drift of channel {ch} per unit of {f}")
                 for ch in self.channels for f in self.features]
        if self.absolute:
            specs += [ParamSpec(f"TD_{ch}_zero", "um", self.key(), False,
                                f"reading of channel {ch} with every feature at zero") for ch in self.channels]
        return specs

    def context_names(self, machine):
        return list(self.features)

    def to_dict(self):
        d = super().to_dict()
        d["features"] = list(self.features)
        d["channels"] = list(self.channels)
        return d


TERM_CLASSES = {cls.kind: cls for cls in
                (Backlash, PeriodicError, FeedOffset, AbbeIRC, RotaryErrorMotion, ThermalDrift,
                 ChannelDrift)}


def term_from_dict(data: dict, path=None) -> Term:
    from ..errors import InputError
    if not isinstance(data, dict) or data.get("kind") not in TERM_CLASSES:
        raise InputError(f"unknown model term {data!r} (known kinds: {', '.join(TERM_CLASSES)})", path)
    cls = TERM_CLASSES[data["kind"]]
    kwargs = {k: v for k, v in data.items() if k != "kind"}
    for key in ("features", "channels"):
        if key in kwargs:
            kwargs[key] = tuple(kwargs[key])
    try:
        return cls(**kwargs)
    except TypeError as exc:
        raise InputError(f"model term {data['kind']!r}: {exc}", path) from None
