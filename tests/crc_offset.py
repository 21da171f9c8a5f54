"""The tool centre's path under cutter radius compensation, computed for the tests from the
controllers' descriptions and sharing no code with mtcomp (the moves come from `replay`, the tests'
own reading of a program).

The rules (FANUC Series 30i/31i/32i-MA User's Manual B-63944EN-2/02, 6.6 "Cutter compensation";
FANUC Series 16/18-MODEL C Operator's Manual, 15.4; LinuxCNC G-code reference, G41/G42): in the
offset plane (G17: X Y) every move is offset by the tool radius R to the left (G41, Heidenhain RL)
or the right (G42, RR) of its own direction; a straight move's offset is the parallel line, an
arc's the concentric arc. Where two offset moves meet, an inside corner is cut to the intersection
of the two offsets and an outside corner is rounded by an arc of radius R about the programmed
corner (type C; LinuxCNC inserts that arc, FANUC's type C its chords). A move without motion in
the plane (a plunge of Z) is not offset in it: the offset vector stays as it was. The start-up
move (the first move in the plane after G41/G42) runs from the uncompensated start to its offset
end, the cancel move (G40) from its offset start to the uncompensated end; a G40 line without
motion in the plane ends the offset where the tool stands.

`centre_path` gives the tool centre's path of each stretch under compensation; `compare_centres`
checks that a compensated program's path is its source's moved by no more than the correction.
"""
import math
import re
from dataclasses import dataclass

import numpy as np

from replay import replay, without_comments

_CRC = re.compile(r"G0*4([012])(?![\d.])")


def heidenhain_as_gcode(text: str) -> bytes:
    """The straight `L` blocks of a Heidenhain conversational program as G-code lines, line for
    line (RL G41, RR G42, R0 G40, FMAX a rapid; the other lines empty)."""
    out = []
    for line in text.splitlines():
        m = re.match(r"\s*\d+\s+L\s+(.*)", line)
        if not m:
            out.append("")
            continue
        body = m.group(1)
        words = " ".join(f"{a}{v}" for a, v in re.findall(r"\b([XYZ])([-+]?[\d.]+)", body))
        comp = {"RL": "G41 ", "RR": "G42 ", "R0": "G40 "}
        code = next((g for k, g in comp.items() if re.search(rf"\b{k}\b", body)), "")
        out.append(f"{code}{'G0' if 'FMAX' in body else 'G1'} {words}")
    return "\n".join(out).encode()


@dataclass
class Element:
    """One move under compensation in the plane: programmed start, end (2,), for an arc its
    centre and signed sweep (rad, counter-clockwise positive), the side (+1 left, -1 right)."""
    line: int
    p0: np.ndarray
    p1: np.ndarray
    centre: np.ndarray = None
    sweep: float = 0.0
    side: int = 1

    def tangent(self, at_end: bool) -> np.ndarray:
        if self.centre is None:
            d = self.p1 - self.p0
            return d / np.hypot(*d)
        r = (self.p1 if at_end else self.p0) - self.centre
        t = np.array([-r[1], r[0]]) if self.sweep > 0 else np.array([r[1], -r[0]])
        return t / np.hypot(*t)

    def offset_radius(self, R: float) -> float:
        return float(np.hypot(*(self.p0 - self.centre))) - self.side * math.copysign(R, self.sweep)


def _left(t):
    return np.array([-t[1], t[0]])


def _xy(pos):
    return np.array([pos["X"], pos["Y"]], dtype=float)


def stretches(data: bytes):
    """The stretches under compensation: each (start (2,), elements, end (2,)), the start and end
    the uncompensated positions where the offset begins and ends."""
    moves = replay(data).moves
    by_line = {}
    for m in moves:
        by_line.setdefault(m.line, []).append(m)
    side, run, out = 0, None, []
    pos = None
    for index, raw in enumerate(data.split(b"\n")):
        codes = _CRC.findall(without_comments(raw.decode("latin-1")).upper())
        code = int(codes[-1]) if codes else None
        cancel = code == 0 and side != 0
        if code in (1, 2):
            side = 1 if code == 1 else -1
        for m in by_line.get(index, []):
            assert m.plane == 17, "the tests' compensation follows G17 only"
            a, b = _xy(m.start), _xy(m.end)
            moves_plane = m.kind == "arc" or np.hypot(*(b - a)) > 1e-9
            if side and moves_plane:
                if run is None:
                    run = (a, [])
                el = Element(index, a, b, None if m.kind != "arc" else np.array(m.centre, float),
                             m.sweep, side)
                run[1].append(el)
            pos = b
        if cancel:
            if run is not None:
                out.append((run[0], run[1], pos))
            run, side = None, 0
    return out


def _intersect(e1: Element, e2: Element, R: float, guess: np.ndarray) -> np.ndarray:
    """The intersection of the offsets of e1 and e2 nearest ``guess`` (None if they miss)."""
    def shape(e, at_end):
        if e.centre is None:
            t = e.tangent(at_end)
            return ("line", e.p0 + e.side * R * _left(t), t)
        return ("circle", e.centre, e.offset_radius(R))
    s1, s2 = shape(e1, True), shape(e2, False)
    if s1[0] == "circle" and s2[0] == "line":
        s1, s2 = s2, s1
    if s1[0] == "line" and s2[0] == "line":
        A = np.array([s1[2], -s2[2]]).T
        if abs(np.linalg.det(A)) < 1e-12:
            return None
        t = np.linalg.solve(A, s2[1] - s1[1])
        return s1[1] + t[0] * s1[2]
    if s1[0] == "line":             # line p + t d against circle c, r
        p, d = s1[1], s1[2]
        c, r = s2[1], s2[2]
        f = p - c
        bq, cq = f @ d, f @ f - r * r
        disc = bq * bq - cq
        if disc < 0:
            return None
        pts = [p + (-bq + sg * math.sqrt(disc)) * d for sg in (1, -1)]
    else:                           # two circles
        c1, r1, c2, r2 = s1[1], s1[2], s2[1], s2[2]
        dv = c2 - c1
        dist = np.hypot(*dv)
        if dist < 1e-12:
            return None
        a = (r1 * r1 - r2 * r2 + dist * dist) / (2 * dist)
        h2 = r1 * r1 - a * a
        if h2 < 0:
            return None
        mid = c1 + a * dv / dist
        perp = np.array([-dv[1], dv[0]]) / dist
        pts = [mid + sg * math.sqrt(h2) * perp for sg in (1, -1)]
    return min(pts, key=lambda q: np.hypot(*(q - guess)))


def _samples(e: Element, a: np.ndarray, b: np.ndarray, R: float, n: int = 24):
    """Points of e's offset from a to b (the ends the corners gave it)."""
    if e.centre is None:
        return [a + (b - a) * k / n for k in range(n + 1)]
    r = e.offset_radius(R)
    a0 = math.atan2(*(a - e.centre)[::-1])
    a1 = math.atan2(*(b - e.centre)[::-1])
    sweep = (a1 - a0) % (2 * math.pi) if e.sweep > 0 else -((a0 - a1) % (2 * math.pi))
    return [e.centre + r * np.array([math.cos(a0 + sweep * k / n), math.sin(a0 + sweep * k / n)])
            for k in range(n + 1)]


def centre_path(data: bytes, R: float):
    """Per stretch under compensation: (points (m, 2) along the tool centre's path, corners: a dict
    (line before, line after) -> the tool centre's point at an inside corner, or at the middle
    of the arc about an outside one, lines: the lines of the moves offset in the plane)."""
    out = []
    for start, els, end in stretches(data):
        ends = [start]           # the offset ends of each element: ends[2k], ends[2k+1]
        corners = {}
        arcs = {}
        for e1, e2 in zip(els, els[1:]):
            P = e1.p1
            t1, t2 = e1.tangent(True), e2.tangent(False)
            A, B = P + e1.side * R * _left(t1), P + e2.side * R * _left(t2)
            turn = t1[0] * t2[1] - t1[1] * t2[0]
            key = (e1.line, e2.line)
            if abs(turn) < 1e-12 and t1 @ t2 > 0:
                ends += [A, A]
                corners[key] = A
            elif e1.side * turn > 0:
                X = _intersect(e1, e2, R, (A + B) / 2)
                X = (A + B) / 2 if X is None else X
                ends += [X, X]
                corners[key] = X
            else:
                mid = A + B - 2 * P
                corners[key] = P + R * mid / np.hypot(*mid) if np.hypot(*mid) > 1e-12 else A
                ends += [A, B]
                arcs[len(ends) - 2] = P
        ends.append(end)
        pts = []
        for k, e in enumerate(els):
            pts += _samples(e, ends[2 * k], ends[2 * k + 1], R)
            if 2 * k + 1 in arcs:
                P = arcs[2 * k + 1]
                a, b = ends[2 * k + 1] - P, ends[2 * k + 2] - P
                ang = math.atan2(a[0] * b[1] - a[1] * b[0], a @ b)
                a0 = math.atan2(a[1], a[0])
                pts += [P + R * np.array([math.cos(a0 + ang * j / 12), math.sin(a0 + ang * j / 12)])
                        for j in range(13)]
        corners["start"], corners["end"] = start, end
        out.append((np.array(pts), corners, [e.line for e in els]))
    return out


def _to_path(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Distance of each point to the polyline ``path``."""
    a, b = path[:-1], path[1:]
    d = b - a
    L2 = np.maximum((d * d).sum(axis=1), 1e-30)
    best = np.full(len(points), np.inf)
    for i, p in enumerate(points):
        t = np.clip(((p - a) * d).sum(axis=1) / L2, 0.0, 1.0)
        q = a + t[:, None] * d
        best[i] = np.min(np.hypot(*(q - p).T))
    return best


def compare_centres(src: bytes, out: bytes, R: float):
    """The tool centre's paths of a program and its compensated version, compared stretch by
    stretch: (largest distance of either path from the other (mm), largest move of a corner point
    less the correction of its programmed corner (mm), largest programmed correction in the plane
    (mm)). Asserts that the same lines move in the plane in both."""
    a, b = centre_path(src, R), centre_path(out, R)
    assert [s[2] for s in a] == [s[2] for s in b], \
        f"moves in the plane differ: {[s[2] for s in a]} != {[s[2] for s in b]}"
    far = swing = corr = 0.0
    pa = {e.line: e for _s, els, _e in stretches(src) for e in els}
    pb = {e.line: e for _s, els, _e in stretches(out) for e in els}
    for (pts_a, cor_a, _), (pts_b, cor_b, _) in zip(a, b):
        far = max(far, float(_to_path(pts_b, pts_a).max()), float(_to_path(pts_a, pts_b).max()))
        for key, va in cor_a.items():
            if key in ("start", "end"):
                c = cor_b[key] - va
            else:
                c = pb[key[0]].p1 - pa[key[0]].p1
            corr = max(corr, float(np.hypot(*c)))
            swing = max(swing, float(np.hypot(*(cor_b[key] - va - c))))
    return far, swing, corr
