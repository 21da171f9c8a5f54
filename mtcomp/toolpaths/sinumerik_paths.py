"""What a Siemens Sinumerik 840D block says about the path besides its end point: the settings of
path control that move nothing, the circle given by its radius ``CR=``, the programmable zero
offset ``TRANS``/``ATRANS`` and the blocks in machine coordinates ``SUPA``/``G53``/``G153``.

The rules are those of Siemens AG, SINUMERIK 840D sl Programming Manual, Fundamentals (2013):
continuous-path mode and smoothing (``G64``, ``G641``-``G645`` with ``ADIS=``/``ADISPOS=``),
acceleration behaviour (``SOFT``, ``BRISK``, ``DRIVE``), feedforward control (``FFWON``,
``FFWOF``), NC block compression (``COMPON``, ``COMPCURV``, ``COMPCAD``, ``COMPOF``), the feed
profile ``FNORM``, the feed reduction at corners (``G62``, ``G621``, ``FENDNORM``; Job planning,
"Feed reduction with corner deceleration"), the dwell ``G4``, the preprocessing stop ``STOPRE``,
messages ``MSG``, circular interpolation with radius and end point (``CR=``), frames (``TRANS``, ``ATRANS``) and
the suppression of frames (``G53``, ``G153``, ``SUPA``); the high-speed settings cycle CYCLE832
is Siemens AG, SINUMERIK 840D sl / 828D Cycles, Programming Manual (2013). Each of these smooths,
times or shifts the path the program states; none moves an axis by itself.
"""
from __future__ import annotations

import math

import numpy as np

#: words that set how the controller follows the programmed path (within a tolerance the program
#: or the machine data set) and move nothing: accepted, kept byte for byte
SETTING_WORDS = {"SOFT", "BRISK", "DRIVE", "FFWON", "FFWOF", "COMPON", "COMPCURV", "COMPCAD",
                 "COMPOF", "STOPRE", "TRAFOOF", "FNORM", "FENDNORM"}
#: calls that set (CYCLE832: the tolerance and the smoothing of high-speed machining) or show
#: (MSG: a message on the operator's screen) and move nothing
SETTING_CALLS = {"CYCLE832", "MSG"}
#: values that belong to a setting, not to a variable of the program
SETTING_VALUES = {"ADIS", "ADISPOS"}
#: the continuous-path modes with smoothing: the path between the programmed points is rounded
#: within a tolerance; the corrections are written on the programmed points
SMOOTHING_G = {641, 642, 643, 644, 645}
#: the feed reduced at corners (G62 inside corners under G41/G42, G621 every corner; FENDNORM
#: off): the feed along the path, not the path
CORNER_G = {62, 621}
#: the suppression of frames in one block: its positions are machine positions
MACHINE_G = {53, 153}
#: the frame instructions read: TRANS and ATRANS with X Y Z, and without values the ones that
#: clear the programmable frame
FRAME_WORDS = {"TRANS", "ATRANS", "ROT", "SCALE", "MIRROR"}


class RadiusError(ValueError):
    """A circle given by CR= that no controller can make (the message says why)."""


def radius_centre(start, end, radius: float, ccw: bool, scale: float = 1.0) -> tuple[float, float]:
    """The centre (x, y) of the circle from ``start`` to ``end`` (x, y) of radius ``|radius|``,
    counter-clockwise (G3) or clockwise (G2); a positive radius turns at most 180 degrees, a
    negative one more (Fundamentals, circular interpolation with radius and end point): the rule
    of an R arc (:func:`~._arcs.centre_from_radius`, with its tolerance on a half circle whose
    chord is a little longer than the diameter), with Sinumerik's messages. ``scale``: mm per
    unit of the values (25.4 in inch: the tolerance is in mm)."""
    from ._arcs import ARC_RADIUS_TOL_MM, ARC_RADIUS_TOL_REL, centre_from_radius
    s, e = np.asarray(start, dtype=float) * scale, np.asarray(end, dtype=float) * scale
    half = 0.5 * math.hypot(*(e - s))
    if half <= 5e-10:
        raise RadiusError("a circle by its radius CR= that ends where it starts (a full circle is "
                          "programmed with its centre)")
    if half - abs(radius) * scale > max(ARC_RADIUS_TOL_MM, ARC_RADIUS_TOL_REL * abs(radius) * scale):
        unit = "in" if scale != 1.0 else "mm"
        raise RadiusError(f"CR={abs(radius):g} is smaller than half the chord ({half / scale:.6g} "
                          f"{unit}) to its end point")
    cx, cy = centre_from_radius(s, e, radius * scale, ccw)
    return float(cx) / scale, float(cy) / scale


def signed_radius(start, end, centre, ccw: bool) -> float:
    """The CR= value of the circle from ``start`` to ``end`` (x, y) whose centre is the point of
    the chord's perpendicular bisector nearest ``centre``: its radius, negative where the circle
    turns more than 180 degrees."""
    (sx, sy), (ex, ey), (cx, cy) = start, end, centre
    dx, dy = ex - sx, ey - sy
    chord = math.hypot(dx, dy)
    left = ((cx - sx - 0.5 * dx) * -dy + (cy - sy - 0.5 * dy) * dx) / chord
    r = math.hypot(0.5 * chord, left)
    return -r if (left < 0) == ccw else r
