"""An arc that no single arc can carry is split into as few pieces as the chord tolerance allows,
none of them a micro-arc, with radii near the arc's own.

The case is the Haas program of the corpus (``N180 G02 X5.25 Y0. I-5.25 J0.``: a full circle of
radius 5.25 mm) under a model with only a backlash of X (30 um): the correction flips where X
reverses, so the corrected path is two half circles shifted apart with a ramp between them. The
oracle reads the written pieces back with the tests' own controller replay (tests/replay.py),
computes their lengths and radii here, and checks the replayed path against the planned one (the
nominal circle plus the planned corrections of BLOCKS.csv, interpolated by angle)."""
import csv
import math

import numpy as np
import pytest

from mtcomp.cli import main
from replay import replay
from test_planner_reversal_written import BL_UM, _model

CENTRE, R = np.array([100.0, 0.0]), 5.25
TWO_CIRCLES = ("G21 G90 G17 G54\nG0 X105.25 Y0 Z5\nG1 Z-5 F200\n"
               "G2 X105.25 Y0 I-5.25 J0 F1120\nG1 Z-10 F200\nG2 X105.25 Y0 I-5.25 J0 F1120\n"
               "G0 Z100\nM30\n")
ARC_LINES = (4, 6)
TOL_MM = 1e-3
#: hand-derived: half the chord whose sagitta on r = 5.25 mm is 1 um, sqrt(0.001 * 10.499)
MIN_PIECE_MM = 0.10246


@pytest.fixture(scope="module")
def compensated(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pieces")
    prog, out, rep = tmp / "p.nc", tmp / "o.nc", tmp / "b.csv"
    prog.write_text(TWO_CIRCLES)
    assert main(["compensate", "xfyz", str(_model(tmp)), str(prog), "-o", str(out), "--report",
                 str(rep), "--chord-tol-um", str(TOL_MM * 1e3), "--quiet"]) == 0
    with open(rep, newline="") as f:
        rows = list(csv.DictReader(f))
    return out.read_bytes(), rows


def _pieces(data: bytes, line: int):
    """The written arc pieces of source line ``line`` (one of ARC_LINES: the first or the second
    run of consecutive arc moves of the output; a split arc's later pieces follow on lines of their
    own): (start (2,), centre (2,), signed sweep, radius at the start, radius at the end, length
    along the arc)."""
    runs, last = [], None
    for m in replay(data).moves:
        if m.kind == "arc":
            if last is None or m.line != last + 1:
                runs.append([])
            runs[-1].append(m)
            last = m.line
    assert len(runs) == len(ARC_LINES)
    out = []
    for m in runs[ARC_LINES.index(line)]:
        s = np.array([m.start["X"], m.start["Y"]])
        e = np.array([m.end["X"], m.end["Y"]])
        c = np.array(m.centre)
        r0, r1 = float(np.hypot(*(s - c))), float(np.hypot(*(e - c)))
        out.append((s, c, m.sweep, r0, r1, 0.5 * (r0 + r1) * abs(m.sweep)))
    return out


def _sample(piece, k=400):
    """(k, 2) points along a written piece, as the controller interpolates it (the radius
    linear in the angle)."""
    s, c, sweep, r0, r1, _length = piece
    t = (np.arange(k) + 0.5) / k
    a = math.atan2(s[1] - c[1], s[0] - c[0]) + sweep * t
    r = r0 + (r1 - r0) * t
    return c + r[:, None] * np.c_[np.cos(a), np.sin(a)]


def _planned(rows, line):
    """(angles about the nominal centre, clockwise from the start, (n,); corrections (n, 2) mm)
    of the planned points of a line, the arc's start (correction of the row before) first."""
    idx = [i for i, r in enumerate(rows) if r["line"] == str(line)]
    pts = np.array([[float(rows[i]["x_mm"]), float(rows[i]["y_mm"])] for i in idx])
    corr = np.array([[float(rows[i]["cx_um"]), float(rows[i]["cy_um"])] for i in idx]) * 1e-3
    before = rows[idx[0] - 1]
    c0 = np.array([float(before["cx_um"]), float(before["cy_um"])]) * 1e-3
    nominal = pts - corr
    turn = np.mod(-np.arctan2(nominal[:, 1] - CENTRE[1], nominal[:, 0] - CENTRE[0]), 2 * np.pi)
    turn[-1] = 2 * np.pi                           # the full circle's end
    return np.concatenate([[0.0], turn]), np.vstack([c0, corr])


@pytest.mark.parametrize("line", ARC_LINES)
def test_few_pieces_none_short_radii_near_the_arcs(compensated, line):
    data, _rows = compensated
    pieces = _pieces(data, line)
    lengths = np.array([p[5] for p in pieces])
    radii = np.array([[p[3], p[4]] for p in pieces])
    # the pieces close the circle
    assert lengths.sum() == pytest.approx(2 * math.pi * R, rel=2e-3)
    # two half circles of one correction each, three ramps between (at the start, where X reverses
    # at the far side, at the end): at most one arc per half and one per side of each ramp.
    # Halving the stretch until each half fits (what the writer did) gave 20 and 16 pieces
    assert 3 <= len(pieces) <= 8, len(pieces)
    assert lengths.min() >= MIN_PIECE_MM, lengths
    # no radius far from the arc's own (halving gave 3.99 and 7.66 mm)
    assert np.all(np.abs(radii - R) <= 0.15 * R), radii
    # where the correction is one translation, the radius is the arc's own: the long pieces
    long = lengths > 0.25 * lengths.sum()
    assert long.sum() >= 2
    np.testing.assert_allclose(radii[long], R, rtol=0, atol=2e-3)


def _gap(points, pieces):
    """(n,) distance (mm) of each of points (n, 2) to the nearest written piece, each as the
    controller interpolates it (the radius linear in the angle; off its angles, its nearer end)."""
    best = np.full(len(points), np.inf)
    for s, c, sweep, r0, r1, _length in pieces:
        e = c + r1 * np.array([math.cos(math.atan2(*(s - c)[::-1]) + sweep),
                               math.sin(math.atan2(*(s - c)[::-1]) + sweep)])
        turn = (np.arctan2(points[:, 1] - c[1], points[:, 0] - c[0])
                - math.atan2(s[1] - c[1], s[0] - c[0])) * np.sign(sweep) % (2 * np.pi)
        inside = turn <= abs(sweep)
        r = r0 + (r1 - r0) * turn / abs(sweep)
        d = np.where(inside, np.abs(np.hypot(*(points - c).T) - r), np.inf)
        best = np.minimum.reduce([best, d, np.hypot(*(points - s).T), np.hypot(*(points - e).T)])
    return best


def _min_dist(points, path):
    """(n,) distance (mm) of each of points (n, 2) to the nearest of path (m, 2)."""
    return np.array([np.min(np.hypot(*(path - p).T)) for p in points])


@pytest.mark.parametrize("line", ARC_LINES)
def test_the_written_pieces_follow_the_planned_path(compensated, line):
    """The written pieces against the planned path (the nominal circle plus the planned correction
    interpolated by angle between the planned points), both ways: every point of either is near
    the other path."""
    data, rows = compensated
    pieces = _pieces(data, line)
    turn, corr = _planned(rows, line)
    t = np.linspace(0.0, 2 * np.pi, 200_001)
    planned = CENTRE + R * np.c_[np.cos(-t), np.sin(-t)] + np.c_[
        np.interp(t, turn, corr[:, 0]), np.interp(t, turn, corr[:, 1])]
    written = np.vstack([_sample(p, 1000) for p in pieces])
    # the tolerance, the rounding of the written words (0.05 um each) and the sampling (< 0.01 um)
    slack = 2e-4
    miss = _min_dist(written[::7], planned)
    assert miss.max() <= TOL_MM + slack, miss.max()
    points = CENTRE + R * np.c_[np.cos(-turn[1:]), np.sin(-turn[1:])] + corr[1:]
    dense = np.vstack([_sample(p, 20_000) for p in pieces])
    gap = _min_dist(points, dense)
    assert gap.max() <= TOL_MM + slack, gap.max()


def test_the_written_pieces_are_never_worse(compensated):
    """Along the written path the tool's distance from the nominal circle, the backlash added by
    hand (+-BL/2 in X with the direction X moves in), is never larger
    than without correction at the same angle, beyond the tolerance."""
    data, rows = compensated
    for line in ARC_LINES:
        arc = [r for r in rows if r["line"] == str(line)]
        written = np.vstack([_sample(p, 2000) for p in _pieces(data, line)])
        theta = np.arctan2(written[:, 1] - CENTRE[1], written[:, 0] - CENTRE[0])
        # X's direction at the nominal point of the same angle (clockwise: X grows above the
        # centre); a written arc may turn X back by a few nm where the nominal X turns (at the
        # start), far below the words' 0.1 um
        d_x = np.sign(np.sin(theta))
        # the model's sign from the planned rows: before = s * BL / 2 * d_x
        pts = np.array([[float(r["x_mm"]), float(r["y_mm"])] for r in arc])
        d_rows = np.sign(pts[:, 1] - CENTRE[1])
        before_rows = np.array([float(r["ex_before_um"]) for r in arc])
        s = np.sign(np.median(before_rows[d_rows != 0] / d_rows[d_rows != 0]))
        err = np.c_[s * BL_UM / 2 * d_x * 1e-3, np.zeros(len(d_x))]
        nominal = CENTRE + R * np.c_[np.cos(theta), np.sin(theta)]
        before = np.abs(np.hypot(*(nominal + err - CENTRE).T) - R) * 1e3
        after = np.abs(np.hypot(*(written + err - CENTRE).T) - R) * 1e3
        # not in the chord where X reverses (sin theta = 0; a chord spans 0.039 rad): the planned
        # correction ramps through the reversal between its two ends, so the error flips within it
        keep = np.abs(np.sin(theta)) > 0.04
        assert np.all(after[keep] <= before[keep] + TOL_MM * 1e3 + 0.2), \
            np.max(after[keep] - before[keep])


def test_the_summary_says_how_far_the_written_arcs_miss_their_path(tmp_path, capsys):
    """compensate's note on the arcs it wrote in pieces: their largest miss off the corrected path,
    which the test measures itself from the written pieces and the planned points (as above)."""
    import re
    prog, out, rep = tmp_path / "p.nc", tmp_path / "o.nc", tmp_path / "b.csv"
    prog.write_text(TWO_CIRCLES)
    assert main(["compensate", "xfyz", str(_model(tmp_path)), str(prog), "-o", str(out),
                 "--report", str(rep), "--chord-tol-um", str(TOL_MM * 1e3)]) == 0
    said = re.search(r"the arcs written miss their corrected path by up to ([0-9.]+) um",
                     capsys.readouterr().out)
    assert said, "no note on the written arcs"
    with open(rep, newline="") as f:
        rows = list(csv.DictReader(f))
    data, gaps = out.read_bytes(), []
    for line in ARC_LINES:
        turn, corr = _planned(rows, line)
        points = CENTRE + R * np.c_[np.cos(-turn[1:]), np.sin(-turn[1:])] + corr[1:]
        # the distance to the pieces themselves (points 0.5 um apart along them read up to 0.03
        # um more at 1 um off)
        gaps.append(_gap(points, _pieces(data, line)).max())
    assert 0.1 < max(gaps) * 1e3 <= 1.0 + 0.2
    # BLOCKS.csv writes the planned positions to 0.1 um: the points read back from it lie up to
    # 0.05 * sqrt(2) um from the writer's own (a piece whose centre moves least misses by the
    # whole tolerance, so its note reads 1.00 um)
    assert float(said.group(1)) == pytest.approx(max(gaps) * 1e3, abs=0.075)

