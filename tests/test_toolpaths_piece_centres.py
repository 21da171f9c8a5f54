"""A split arc's pieces keep the source's circle where the path allows: each piece's centre is the
source's moved by the correction, or the nearest to it that holds, never a circle a machinist
would not recognise as the corner's.

The case, by hand: a quarter arc of radius 10 mm about (40, -15) from (40, -25) to (50, -15),
counter-clockwise, corrected by c(t) = (30 t^2, -20 t (1 - t)) um where t in [0, 1] is the fraction
of the quarter turned (t = 0 before the arc, 1 after it). |c|^2 = 900 t^4 + 400 t^2 (1 - t)^2 grows
with t (both terms' sum has a positive derivative on (0, 1]), so the largest correction is
|c(1)| = 30 um. The corrected path leaves every circle by more than the 1 um chord tolerance (its
curvature changes with the t^2 term), so the arc is written in pieces; each piece's centre is then
within 30 um + 1 um (the tolerance) of (40, -15), plus the rounding of the written centre words
(0.05 um each). The writers used to fit any circle through a piece's ends: a 41.9 um move of the
centre for the second piece of two. Every piece must still hold the corrected path within the
tolerance: checked against the path c(t) gives, as each controller's replay interpolates the
written pieces (tests/replay.py, replay_heidenhain.py, replay_sinumerik.py)."""
import math

import numpy as np
import pytest

import replay
import replay_heidenhain
import replay_sinumerik
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks, write_corrected

XFYZ = load_machine("xfyz")
CENTRE, R = np.array([40.0, -15.0]), 10.0
TOL_MM, MAX_C_MM = 1e-3, 0.030
#: the written centre words' rounding (4 decimals: 0.05 um each way) and float slack
ROUND_MM = 1e-4
PROGRAMS = {
    "gcode": ("p.nc", "G21 G90 G17\nG0 X40 Y-25 Z5\nG1 Z-5 F300\nG3 X50 Y-15 I0 J10 F1000\n"
                      "G1 Y15\nM30\n", replay.replay),
    "heidenhain": ("p.h", "0 BEGIN PGM T MM\n1 L X+40 Y-25 Z+5 R0 FMAX\n2 L Z-5 F300\n"
                          "3 CC X+40 Y-15\n4 C X+50 Y-15 DR+ F1000\n5 L Y+15\n6 END PGM T MM\n",
                   replay_heidenhain.replay),
    "sinumerik": ("p.mpf", "%_N_T_MPF\nN10 G17 G90 G71\nN20 G0 X40 Y-25 Z5\nN30 G1 Z-5 F300\n"
                           "N40 G3 X50 Y-15 I=AC(40) J=AC(-15) F1000\nN50 G1 Y15\nN60 M30\n",
                  replay_sinumerik.replay),
}


def _turned(p):
    """t (n,): the fraction of the quarter turned at points p (n, >= 2), clipped to [0, 1]."""
    angle = np.arctan2(p[:, 1] - CENTRE[1], p[:, 0] - CENTRE[0])
    return np.clip((angle + math.pi / 2) / (math.pi / 2), 0.0, 1.0)


def _correction(p):
    t = _turned(p)
    c = np.zeros((len(p), 3))
    c[:, 0], c[:, 1] = 0.030 * t ** 2, -0.020 * t * (1 - t)
    return c


def _corrections(path):
    for chunk in iter_segment_chunks(path, XFYZ):
        yield chunk, chunk.end + _correction(chunk.end), np.ones(len(chunk), np.int64)


@pytest.mark.parametrize("dialect", sorted(PROGRAMS))
def test_every_piece_of_a_split_arc_keeps_the_corrected_centre(tmp_path, dialect):
    name, text, replayed = PROGRAMS[dialect]
    src, out = tmp_path / name, tmp_path / ("o" + name[1:])
    src.write_text(text)
    write_corrected(src, out, XFYZ, _corrections(src))
    arcs = [m for m in replayed(out.read_bytes()).moves if m.kind == "arc"]
    assert len(arcs) >= 2, "the arc is not split: the case no longer tests the pieces"
    off = [math.hypot(*(np.array(m.centre) - CENTRE)) for m in arcs]
    assert max(off) <= MAX_C_MM + TOL_MM + ROUND_MM, np.round(np.array(off) * 1e3, 2)
    # the pieces hold the corrected path: points of the nominal quarter plus c(t), each within the
    # tolerance (and the words' rounding) of the piece that turns through its angle
    t = np.linspace(0.0, 1.0, 2001)
    nominal = CENTRE + R * np.c_[np.cos(-math.pi / 2 + t * math.pi / 2),
                                 np.sin(-math.pi / 2 + t * math.pi / 2)]
    path = nominal + _correction(nominal)[:, :2]
    gap = np.full(len(path), np.inf)
    for m in arcs:
        s, e, c = (np.array([m.start["X"], m.start["Y"]]), np.array([m.end["X"], m.end["Y"]]),
                   np.array(m.centre))
        a0 = math.atan2(*(s - c)[::-1])
        turn = (np.arctan2(path[:, 1] - c[1], path[:, 0] - c[0]) - a0) % (2 * math.pi)
        r0, r1 = math.hypot(*(s - c)), math.hypot(*(e - c))
        inside = turn <= abs(m.sweep)
        r = r0 + (r1 - r0) * turn / abs(m.sweep)
        gap = np.where(inside, np.minimum(gap, np.abs(np.hypot(*(path - c).T) - r)), gap)
    assert np.all(np.isfinite(gap)) and gap.max() <= TOL_MM + ROUND_MM, gap.max()
