"""Writing a G-code program back with corrected coordinates: the writer's layer.

:class:`OutputState` keeps what the written program has said so far (distance mode, motion mode,
the last value written per axis); :func:`format_motion_lines` writes one motion line with its
corrected points (the source line with its numbers replaced in place and later pieces, G2/G3 arcs
fitted to the corrected points, or a restated drilling cycle), and
:func:`write_pass_through` copies every other line byte for byte (and counts the moves it passes
through uncorrected). :class:`CorrectionCursor` (:mod:`.cursor`) walks the corrections the planner
hands over, row by row, and :func:`write_corrected` is the pure-Python writer (the public :func:`mtcomp.toolpaths.gcode.write_corrected` prepares the cursor
and runs the compiled writer when it can, with the same bytes).

Output: the input with only the numbers that carry a correction changed (at least the source
word's decimals, and 4 in mm and deg, 5 in inch), in the distance mode (G90/G91) and the units of
the input at each line: an incremental word is the source's increment plus the change of the
correction from where the output stands (:func:`_increment`), so that a line with no change keeps
its word as written; see docs/toolpaths.md for what is rewritten
and what passes through.
"""
from __future__ import annotations

import math
from decimal import Decimal

import numpy as np

from ..io.atomic import atomic_write
from ..machine import Machine
from ._arcs import (FULL_CIRCLE_TOL_MM, PLANE_AXES, PLANE_OFFSET_LETTERS, ArcError, arc_misses,
                    arc_samples, arc_sweep, centre_from_radius, fit_arc_centre,
                    min_piece_length, near_bound, piece_centre, plan_pieces, radius_refused)
from .blocks import MotionBlock
from .cursor import CorrectionCursor
from .modal import ModalState
from .passed import check_passed_start, passed_cycle
from .reader import iter_blocks, new_state
from .words import (DEFAULT_CHORD_TOL_MM, MM_PER_INCH, SourceLine, base_decimals,
                    cutter_comp_code, format_number, grid_text, increment_text, machine_units,
                    number_decimals, position_text)


class OutputState:
    """What the written program has said so far (shared with the compiled writer).

    absolute : the output is in G90. It follows the input's G90/G91 words, except after a G91
    drilling cycle line, which is written absolute (:func:`_cycle_head`). motion : the motion word
    in force in the output (0, 1, 2, 3; -1 when not known: before the first, after a line that
    changed it in another way). values : (na,) float64, per axis where the output's machine stands
    in the program's frame (mm, rad, as read back from the text written; nan: none yet, or the
    program has lost the axis's position). A coordinate is written when its text differs from that
    of the last value.
    """

    def __init__(self, na: int, state: ModalState | None = None):
        self.absolute = True        # the reader takes a program without G90/G91 as absolute too
        self.motion = -1
        self.cycle_lines = 0        # drilling cycle lines passed through (not corrected)
        self.cycle_blocks = 0       # drilling cycle lines kept as cycles (holes corrected where given)
        #: moves passed through uncorrected (ModalState.passed_move): why -> [lines, first line]
        self.passed_moves = {}
        #: drilling cycles: the R and Z the output's cycle holds ('' : not known), and the Z where
        #: its current series began (mm; nan: not known)
        self.cycle_r = ""
        self.cycle_z = ""
        self.cycle_init_z = math.nan
        self.values = np.full(na, np.nan)
        self.cutter_comp, self.cutter_arc_miss = False, 0.0   # G41/G42 on; a whole arc's miss (mm)
        self.arc_miss = 0.0         # the largest miss of a written arc piece off its path (mm)
        #: source lines that got axis words they did not name (the correction of that axis changed
        #: there), and the first of them (0: none)
        self.added_lines, self.added_line = 0, 0
        self.rotary = [False] * na if state is None else state.rotary
        #: G2/G3 stay in force (False on BeagleG: a new arc piece restates G2/G3, and after the arc
        #: axis words alone move in the G0/G1 mode written before it)
        self.arcs_modal = state is None or state.dialect.arcs_modal
        if state is not None:       # axes known before the first line stand where the reader says
            self.values[state.known] = state.position[state.known]

    def last(self, j: int, inch: bool) -> str:
        """The text of the last written position of axis j in the given units ('' if none)."""
        v = self.values[j]
        return "" if v != v else grid_text(v, self.rotary[j], inch)

    def count_added(self, line: int, added: list, letters: str) -> None:
        """Count source line ``line`` when ``added`` (the words put on it) holds an axis word (a
        letter of ``letters``)."""
        if any(w[:1].upper() in letters for w in added):
            self.added_lines += 1
            self.added_line = self.added_line or line

    def set_last(self, j: int, text: str, inch: bool) -> None:
        self.values[j] = machine_units(float(text), self.rotary[j], inch)


def _piece_feeds(block: MotionBlock, points: np.ndarray, xyz: list[int]) -> np.ndarray:
    """G93: the F (1/min) of each of the k pieces a block is written as, so that the block keeps its
    time: F / (share of the piece in the block's path length; equal shares without motion in XYZ)."""
    prev = np.vstack([block.start[None, :], points[:-1]])
    seg = np.linalg.norm((points - prev)[:, xyz], axis=1) if xyz else np.zeros(len(points))
    total = float(seg.sum())
    share = seg / total if total > 0 else np.full(len(points), 1.0 / len(points))
    return share


def _decimals(line: SourceLine, letters: str, rotary: list[bool], inch: bool) -> list[int]:
    """Per axis the decimals its corrected coordinate is written with: at least those of its word
    in the line, else of the line's axis and centre words with most, and at least 4 (5 in inch)."""
    own = {}
    most = 0
    for w in line.words:
        if w[0] in "XYZABCIJKR":
            d = number_decimals(line.number(w))
            most = max(most, d)
            own.setdefault(w[0], d)
    return [max(base_decimals(rot, inch), own.get(c, most)) for c, rot in zip(letters, rotary)]


def _edit_head(line: SourceLine, out: OutputState, code: int, incremental: bool) -> None:
    """The line's G90/G91 stay as written; where the output's distance mode differs from the
    line's (after a G91 drilling cycle written absolute) and the line does not say it, G90 or G91
    is put in front. The motion word is kept as written (a G2/G3 written as lines gets G1 in its
    place) and put in front where the output's mode differs."""
    head = []
    distance = motion = None
    for w in line.words:
        if w[0] == "G":
            v = float(line.number(w))
            if v in (90, 91):
                distance = w
            elif v in (0, 1, 2, 3):
                motion = w
    g = line.letter("G")
    if distance is None and out.absolute == incremental:
        head.append(g + ("91" if incremental else "90"))
    out.absolute = not incremental
    if motion is not None:
        if float(line.number(motion)) != code:
            line.replace_word(motion, f"{g}{code}")
    elif out.motion != code:
        head.append(f"{g}{code}")
    out.motion = code
    line.insert_head(head)


def _axis_texts(block: MotionBlock, p: np.ndarray, rotary: list[bool], out: OutputState,
                decs: list[int], named) -> list[tuple[int, str | None]]:
    """The axes a piece writes, ``(axis, text)``: a named axis always (text None: its source
    word, whose value it keeps), any other known axis whose text at 4 (5) decimals differs from
    the output's last; never an axis the program has not positioned (nor Z where the tip's Z is not
    known: a W quill's place lost, :mod:`.quill`), but as the block names it. named : (na,) bool
    or None. In G91 the text is the increment (:func:`_increment`), written for a named axis
    always and for any other where it is not zero."""
    inch = block.inch
    res = []
    for i, rot in enumerate(rotary):
        if not block.known[i] and (named is None or not named[i]):
            continue
        if block.incremental:
            t = _increment(block, i, p[i], out.values[i], rot, decs[i])
            if named is not None and named[i] or float(t) != 0.0:
                res.append((i, t))
        elif named is not None and named[i]:
            t = position_text(p[i], rot, inch, decs[i])
            keep = t == position_text(block.end[i], rot, inch, decs[i])
            res.append((i, None if keep else t))
        elif grid_text(p[i], rot, inch) != out.last(i, inch):
            res.append((i, position_text(p[i], rot, inch, decs[i])))
    return res


def _increment(block: MotionBlock, i: int, p: float, v: float, rot: bool, dec: int) -> str:
    """The G91 word of axis i for a piece that ends at p (mm, rad) from where the output stands
    (v; nan: where the program stands): the block's own increment plus the change between the
    correction at p and the one the output carries at its start, so that a piece with nothing new
    to correct keeps the source's increment exactly (:func:`~.words.increment_text`)."""
    start = block.start[i] if v != v else v
    change = (p - block.end[i]) - (start - block.start[i])
    return increment_text(block.end[i] - block.start[i], change, rot, block.inch, dec)


def _written(block: MotionBlock, texts, out: OutputState) -> np.ndarray:
    """(na,) where the machine stands after a piece that writes ``texts`` (its values read back)."""
    v = out.values.copy()
    unknown = np.isnan(v)
    v[unknown] = block.start[unknown]
    for i, t in texts:
        if t is None:
            v[i] = block.end[i]
        else:     # G91: the increment from where the output stands
            v[i] = (v[i] if block.incremental else 0.0) + machine_units(float(t), out.rotary[i],
                                                                         block.inch)
    return v


def _apply_axes(block: MotionBlock, line: SourceLine, texts, letters: str, out: OutputState,
                first: bool) -> list[str]:
    """Set the output's last values; on the first piece replace the named words' numbers in
    place. Returns the words to add (those the line does not name, in the line's case)."""
    added = []
    for i, t in texts:
        if t is None:
            out.values[i] = block.end[i]
            continue
        w = line.find(letters[i]) if first and block.given[i] else None
        said = t
        if block.incremental:       # G91: the increment from where the output stands
            v = out.values[i]
            start = block.start[i] if v != v else v
            if w is not None and Decimal(t) == Decimal(line.number(w)):
                said = None         # the source's own increment keeps its spelling
        if w is not None:
            if said is not None:
                line.replace_number(w, said)
        else:
            added.append(line.letter(letters[i]) + said)
        if block.incremental:
            # the machine moves by the increment written from where it stands (which, after a
            # change of units, need not lie on this unit's grid), as the reader adds it
            out.values[i] = start + machine_units(float(t), out.rotary[i], block.inch)
        else:
            out.set_last(i, t, block.inch)
    return added


def format_motion_lines(block: MotionBlock, points: np.ndarray, letters: str, rotary: list[bool],
                        out: OutputState, ending: str, separator: str = "\n",
                        source: str | None = None, chord_tol: float = DEFAULT_CHORD_TOL_MM,
                        counts: np.ndarray | None = None) -> str:
    """The rewritten text of one motion line whose corrected points are ``points`` (m, na); updates
    ``out``.

    The first piece is the source line itself (``source``, without its ending) with only the
    numbers of the axis words (and arc centre words) whose value changes replaced in place, at
    least with the decimals the word had and at least 4 (5 in inch); an axis the line does not
    name whose written value changes is added after the line's last axis word, in the line's letter
    case; never an axis whose position the program has not given. Word order, case, spacing,
    comments, the N word, the motion word and G90/G91 stay as written (in G91 a word is the
    source's increment plus the change of correction), and G90/G91 or a motion word are put after
    the N word only where the output needs them. Later pieces of a block split into several (inserted nodes, G93 pieces) are new
    lines with what changes. A G2/G3 block stays one arc where the corrected path lies within
    ``chord_tol`` (mm) of one, else it becomes consecutive arcs (:func:`_arc_text`); ``counts`` (k,)
    are the corrected points per chord of the arc (None: one each). A drilling cycle is restated
    by :func:`_cycle_text`. ``ending`` is the line's own ending (kept, '' for a last line without
    one); ``separator`` goes between the lines of a split block.
    """
    if source is None:
        source = " ".join([block.number, f"G{block.motion}"] + list(block.raw.values()) +
                          block.words).strip()
    whole = _cutter_comp(out, source)
    if block.cycle is not None:
        return _cycle_text(block, points, letters, out, ending, separator, source)
    if block.from_arc:
        fit = {} if whole else None       # under G41/G42 one arc, its miss noted; else pieces
        text = _arc_text(block, points, counts, letters, rotary, out, source, chord_tol, separator,
                         fit)
        if text is not None:
            out.cutter_arc_miss = max(out.cutter_arc_miss, fit.get("miss", 0.0) if fit else 0.0)
            return text + ending
        text = None if not whole else _arc_text(block, points, counts, letters, rotary, out,
                                                source, chord_tol, separator)
        if text is not None:
            return text + ending
    return _line_text(block, points, letters, rotary, out, source, ending or separator) + ending


def _line_text(block: MotionBlock, points: np.ndarray, letters: str, rotary: list[bool],
               out: OutputState, source: str, separator: str) -> str:
    """A G0/G1 block (or an arc written as straight pieces): see :func:`format_motion_lines`."""
    code = 0 if block.rapid else 1
    line = SourceLine(source)
    decs = _decimals(line, letters, rotary, block.inch)
    k = points.shape[0]
    g93 = block.inverse_time and k > 1
    if g93:
        share = _piece_feeds(block, points, [i for i, c in enumerate(letters) if c in "XYZ"])
    _edit_head(line, out, code, block.incremental)
    if block.from_arc:
        for w in [w for w in line.words if w[0] in "IJKR"]:
            line.delete(w)
    added = _apply_axes(block, line, _axis_texts(block, points[0], rotary, out, decs, block.given),
                        letters, out, True)
    out.count_added(block.line, added, letters)
    line.insert_at(line.append_pos(), added)
    if g93:
        line.replace_number(line.find("F"), f"{block.f_word / share[0]:.6g}")
        carried = 0.0
    lines = [line.render()]
    for j in range(1, k):
        parts = _apply_axes(block, line, _axis_texts(block, points[j], rotary, out, decs, None),
                            letters, out, False)
        if g93:
            carried += share[j]
        if not parts:
            continue
        if out.motion != code:
            parts.insert(0, f"{line.letter('G')}{code}")
            out.motion = code
        if g93:
            parts.append(f"{line.letter('F')}{block.f_word / carried:.6g}")
            carried = 0.0
        lines.append((line.sep or "").join(parts))
    return separator.join(lines)


def _cycle_head(line: SourceLine, out: OutputState, info) -> None:
    """A drilling cycle line is written absolute: its G91 dropped (G90 where the output is in G91),
    G90 put in front where needed, an incremental line's repeat count dropped."""
    g = line.letter("G")
    distance = [w for w in line.words if w[0] == "G" and float(line.number(w)) in (90, 91)]
    for w in distance:
        if float(line.number(w)) == 91:
            if out.absolute:
                line.delete(w)
            else:
                line.replace_word(w, g + "90")
    if not out.absolute and not distance:
        line.insert_head([g + "90"])
    out.absolute = True
    if info.incremental and info.count_letter is not None:
        line.delete(line.find(info.count_letter))


def _cycle_text(block: MotionBlock, points: np.ndarray, letters: str, out: OutputState, ending: str,
                separator: str, source: str | None) -> str:
    """A drilling cycle line restated with corrected hole positions: points (k, na) are the
    corrected bottoms of its k holes. X, Y and Z take the corrected bottom; R moves with Z (the
    depth below the R plane is kept). The line keeps its words in their order, X Y Z R in their
    places; each is written when the source names it or the output's value differs (those the
    source does not name after its last one). An incremental line becomes absolute, one line per
    repeat (L dropped)."""
    info = block.cycle
    xi, yi, zi = (letters.index(c) for c in "XYZ")
    inch = block.inch
    scale = MM_PER_INCH if inch else 1.0
    if info.starting:
        out.cycle_init_z = out.values[zi]
    out.cycle_blocks += 1
    line = SourceLine(source)
    decs = dict(zip("XYZR", _decimals(line, "XYZR", [False] * 4, inch)))
    raw = {} if info.incremental else {c: line.number(line.find(c)) for c in "XYZR"
                                       if line.find(c) is not None}
    nominal = {"X": block.points[0, xi], "Y": block.points[0, yi], "Z": info.z_bottom,
               "R": info.r_level}
    nominal = {c: position_text(v, False, inch, decs[c]) for c, v in nominal.items()}
    lines = []
    for j in range(points.shape[0]):
        p = points[j]
        v = dict(zip("XYZR", (p[xi], p[yi], p[zi], info.r_level + (p[zi] - block.points[j, zi]))))
        text = {c: position_text(v[c], False, inch, decs[c]) for c in "XYZR"}
        current = {"X": out.last(xi, inch), "Y": out.last(yi, inch), "Z": out.cycle_z,
                   "R": out.cycle_r}
        named = info.named if j == 0 else frozenset("XY")
        need = [c for c in "XYZR" if c in named or grid_text(v[c], False, inch) != current[c]]
        # a coordinate that keeps its source value keeps its source spelling: the machine goes
        # where that spelling says
        said = {c: raw[c] if c in raw and text[c] == nominal[c] else text[c] for c in need}
        if j == 0:
            _cycle_head(line, out, info)
            added = []
            for c in need:
                w = line.find(c)
                if w is None:
                    added.append(line.letter(c) + said[c])
                elif said[c] != line.number(w):
                    line.replace_number(w, said[c])
            out.count_added(block.line, added, "XYZ")
            line.insert_at(line.append_pos("XYZR"), added)
            lines.append(line.render())
        else:
            lines.append(line.sep.join(line.letter(c) + said[c] for c in need))
        for c, i in (("X", xi), ("Y", yi)):
            if c in said:
                out.set_last(i, said[c], inch)
            else:
                out.set_last(i, text[c], inch)
        out.cycle_z, out.cycle_r = (grid_text(float(said.get(c, text[c])) * scale, False, inch)
                                    for c in "ZR")
    r_out = float(out.cycle_r) * scale
    init = out.cycle_init_z
    if info.retract == 99:
        out.values[zi] = r_out
    elif info.retract == 98 and info.z_after_known and init == init and r_out <= init + 1e-9:
        out.values[zi] = init
    else:
        out.values[zi] = math.nan
    out.motion = -1
    return (ending or separator).join(lines) + ending


def _arc_geometry(block: MotionBlock, letters: str):
    """(in-plane columns (2,), nominal centre (2,), the source arc is a full circle)."""
    xyz = [letters.index(c) for c in "XYZ"]
    i0, i1, _ = PLANE_AXES[block.plane]
    cols = (xyz[i0], xyz[i1])
    centre2 = np.asarray(block.centre, dtype=float)[[i0, i1]]
    full = math.hypot(block.end[cols[0]] - block.start[cols[0]],
                      block.end[cols[1]] - block.start[cols[1]]) <= FULL_CIRCLE_TOL_MM
    return cols, centre2, full


class _ArcPiece:
    """One written piece of an arc block: its axis texts, where it ends, its centre words (letter,
    text) or None for a straight piece."""

    def __init__(self, texts, end, centre_words, miss=0.0):
        self.texts, self.end, self.centre_words, self.miss = texts, end, centre_words, miss


def _arc_text(block, points, counts, letters, rotary, out, source, chord_tol, separator, whole=None):
    """One G2/G3 line where the corrected arc (its corrected points, :func:`arc_samples`) lies within
    chord_tol (mm) of an arc from the written start, else consecutive arcs (the corrected points
    halved recursively); None where the block is better written as straight pieces (G93, a rotary
    axis that does not move linearly with the angle, a first piece that is no arc)."""
    if block.centre is None or block.inverse_time and block.points.shape[0] != points.shape[0]:
        return None
    cols, centre2, full = _arc_geometry(block, letters)
    ccw = block.motion == 3
    start_w = _written(block, [], out)
    samples = arc_samples(block.start, block.end, block.points, points, counts, centre2, cols, ccw,
                          full)
    if samples is None:
        return None
    intended, nominal, u = samples
    samples = (np.vstack([start_w[None, :], intended]), np.vstack([block.start[None, :], nominal]),
               np.concatenate([[0.0], u]))
    line = SourceLine(source)
    decs = _decimals(line, letters, rotary, block.inch)
    ctx = _ArcFit(block, line, letters, rotary, out, decs, cols, centre2, full, chord_tol, samples)
    if whole is not None:                 # one arc or none: the path's tolerance lifted
        ctx.path_tol = math.inf
        piece = ctx.arc_piece(0, samples[0].shape[0] - 1, start_w)
        if piece is None:
            return None
        whole["miss"] = ctx.miss
        return ctx.render([piece], separator)
    pieces = ctx.plan(0, samples[0].shape[0] - 1, start_w)
    if not pieces or pieces[0].centre_words is None or (block.inverse_time and len(pieces) > 1):
        return None
    out.arc_miss = max(out.arc_miss, *(p.miss for p in pieces))
    return ctx.render(pieces, separator)


def _cutter_comp(out: OutputState, text: str) -> bool:
    """Whether the line ``text`` is written under cutter radius compensation (it is in force, or the
    line switches it on or off: its entry and exit moves); follows G40/G41/G42 in ``out``."""
    code = cutter_comp_code(text) if "4" in text else None
    if code is None:
        return out.cutter_comp
    out.cutter_comp = code != 40
    return True


#: a rotary axis moving along an arc: its corrected values must follow the written arc's linear
#: interpolation within this (rad: the 1e-4 deg the output writes)
ROTARY_ARC_TOL_RAD = math.radians(1e-4)
#: a fitted arc with a larger radius (mm) is written as straight pieces
MAX_ARC_RADIUS_MM = 1e6


class _ArcFit:
    """The arcs (or, where unavoidable, straight pieces) an arc block is written as.

    samples : (m + 1, na) the written start, then the intended corrected points along the arc
    (:func:`arc_samples`); the pieces end at samples, each checked against the samples it spans."""

    def __init__(self, block, line, letters, rotary, out, decs, cols, centre2, full, chord_tol,
                 samples):
        self.block, self.line, self.letters, self.rotary, self.out = block, line, letters, rotary, out
        self.decs, self.cols, self.centre2, self.full = decs, cols, centre2, full
        self.tol = self.path_tol = chord_tol
        self.miss = 0.0                   # of the last arc that fitted (mm)
        self.samples, self.nominal, self.u = samples
        self.ccw = block.motion == 3
        self.scale = MM_PER_INCH if block.inch else 1.0
        self.letters_c = PLANE_OFFSET_LETTERS[block.plane]
        self.cdecs = _decimals(line, "".join(self.letters_c), [False, False], block.inch)
        self.r_word = line.find("R")
        self.linear = np.array([not r for r in rotary])
        _a0, self.sweep = arc_sweep(block.start[list(cols)], block.end[list(cols)], centre2, self.ccw,
                                    full)
        step = np.diff(self.samples[:, self.linear], axis=0)
        #: (m + 1,) mm along the samples from the written start; pieces at least min_piece long
        self.length = np.concatenate([[0.0], np.cumsum(np.sqrt(np.sum(step * step, axis=1)))])
        self.min_piece = min_piece_length(math.hypot(*(block.start[list(cols)] - centre2)),
                                          chord_tol)
        self.near = near_bound(self.samples, self.nominal, cols, chord_tol)

    def plan(self, a: int, b: int, start_w: np.ndarray) -> list:
        """The pieces from sample a (where the machine stands: start_w) to sample b
        (:func:`~._arcs.plan_pieces`: the longest arcs that hold, a straight piece to the next
        sample only where no arc reaches it)."""
        whole = self.arc_piece(a, b, start_w) if a == 0 else None
        if whole is not None:             # one arc holds: the source's centre or any
            return [whole]
        return plan_pieces(self.arc_piece, self._straight, self.samples, self.length,
                           self.min_piece, a, b, start_w)

    def _straight(self, a: int, start_w: np.ndarray) -> _ArcPiece:
        """A straight piece from sample a (start_w) to sample a + 1."""
        shadow = self._shadow(a, start_w)
        texts = _axis_texts(self.block, self.samples[a + 1], self.rotary, shadow, self.decs,
                            self.block.given if a == 0 else None)
        return _ArcPiece(texts, _written(self.block, texts, shadow), None)

    def _shadow(self, a, start_w):
        if a == 0:
            return self.out
        shadow = OutputState(len(self.rotary))
        shadow.rotary = self.rotary
        shadow.values = np.where(self.block.known, start_w, np.nan)
        return shadow

    def arc_piece(self, a: int, b: int, start_w: np.ndarray, near: bool = False):
        """The arc from start_w through samples a+1 .. b within the tolerance, or None; its centre
        within ``self.near`` of the source's where ``near`` (:func:`~._arcs.plan_pieces`)."""
        block, cols = self.block, list(self.cols)
        full = self.full and a == 0 and b == self.samples.shape[0] - 1
        p = self.samples[b].copy()
        if full:
            p[cols] = start_w[cols]
        shadow = self._shadow(a, start_w)
        texts = _axis_texts(block, p, self.rotary, shadow, self.decs, block.given if a == 0 else None)
        end_w = _written(block, texts, shadow)
        s2, e2 = start_w[cols], end_w[cols]
        gap = math.hypot(*(e2 - s2))
        if (gap > FULL_CIRCLE_TOL_MM) if full else (gap <= FULL_CIRCLE_TOL_MM):
            return None
        # the source's centre moved by the mean correction at the whole arc's ends (as the other
        # writers move an arc's centre), a piece's by that of the points it goes through
        at = [a, b] if a == 0 and b == self.samples.shape[0] - 1 else slice(a + 1, b + 1)
        shift = np.mean(self.samples[at] - self.nominal[at], axis=0)
        shifted = self.centre2 + shift[cols]
        ra, rb = (math.hypot(*(self.nominal[i][cols] - self.centre2)) for i in (a, b))
        radius = 0.5 * (ra + rb)
        # the end radius may differ from the start radius as much as the source's did, and by the
        # tolerance and the rounding of the centre words more
        spiral = abs(rb - ra) + self.tol + 2.0 * 10.0 ** -min(self.cdecs) * self.scale
        inner = self.samples[a + 1:b]
        fitted = fit_arc_centre(s2, e2, inner[:, cols], self.ccw, full, shifted, radius)
        span = (self.u[b] - self.u[a]) * self.sweep

        def holds(centre):
            if centre is None or math.hypot(*(centre - s2)) > MAX_ARC_RADIUS_MM:
                return None
            for words, written in self._centre_words(s2, e2, centre, full):
                if self._fits(start_w, end_w, written, full, inner, span, spiral):
                    return _ArcPiece(texts, end_w, words, self.miss)
            return None

        if full or self.path_tol == math.inf:    # a whole arc: the source's centre or the fitted
            return holds(shifted) or holds(fitted)
        return piece_centre(holds, s2, e2, shifted, fitted,
                            max(self.tol, 10.0 ** -min(self.cdecs) * self.scale), self.centre2,
                            self.near if near else math.inf)

    def _centre_words(self, s2, e2, centre, full):
        """(centre words [(letter, text)], the centre they say (2,)): R where the source has R,
        then I J K."""
        scale = self.scale
        if self.r_word is not None and not full:
            r = math.hypot(*(centre - s2))
            _a0, sweep = arc_sweep(s2, e2, centre, self.ccw, False)
            dec = max(base_decimals(False, self.block.inch),
                      number_decimals(self.line.number(self.r_word)))
            signs = [sweep > math.pi]
            if abs(sweep - math.pi) < 1e-3:     # about a half circle: the source's sign first
                signs = [float(self.line.number(self.r_word)) < 0, sweep <= math.pi]
            for major in signs:
                t = format_number((-r if major else r) / scale, dec)
                try:
                    yield [("R", t)], centre_from_radius(s2, e2, float(t) * scale, self.ccw)
                except ArcError:
                    pass
        # I J K: the centre less the start, or in G90.1 the centre itself (it moves with the
        # correction like an end point)
        base = np.zeros(2) if self.block.absolute_centre else s2
        texts = [format_number((centre[j] - base[j]) / scale, self.cdecs[j]) for j in range(2)]
        yield list(zip(self.letters_c, texts)), base + np.array([float(t) for t in texts]) * scale

    def _fits(self, start_w, end_w, centre, full, inner, span, spiral) -> bool:
        """The arc start_w -> end_w about centre misses none of the points inner by more than the
        tolerance, sweeps within 45 deg of the source's span, and its end radius is within
        ``spiral`` (mm) of its start radius (and within the reader's tolerance)."""
        cols = list(self.cols)
        r0, r1 = math.hypot(*(start_w[cols] - centre)), math.hypot(*(end_w[cols] - centre))
        if abs(r1 - r0) > spiral or radius_refused(r0, r1, self.block.inch):
            return False
        _a0, sweep = arc_sweep(start_w[cols], end_w[cols], centre, self.ccw, full)
        if abs(sweep - span) > 0.25 * math.pi:
            return False
        dist, rot = arc_misses(start_w, end_w, centre, self.cols, self.ccw, full, inner,
                               self.linear)
        self.miss = dist
        return dist <= self.path_tol and rot <= ROTARY_ARC_TOL_RAD

    def render(self, pieces: list, separator: str) -> str:
        """The block's text: the first piece in the source's layout, the others as new lines."""
        line, block, out = self.line, self.block, self.out
        code = block.motion
        linear = out.motion          # BeagleG: the mode axis words alone move in after the arc
        _edit_head(line, out, code, block.incremental)
        first = pieces[0]
        added = _apply_axes(block, line, first.texts, self.letters, out, True)
        out.count_added(block.line, added, self.letters)
        pos = line.append_pos()
        line.insert_at(pos, added)
        self._centre_in_place(first.centre_words)
        lines = [line.render()]
        sep = line.sep or ""
        for piece in pieces[1:]:
            parts = _apply_axes(block, line, piece.texts, self.letters, out, False)
            c = code if piece.centre_words is not None else 1
            if out.motion != c or not out.arcs_modal and c != 1:
                parts.insert(0, f"{line.letter('G')}{c}")
                out.motion = c
            linear = 1 if c == 1 else linear
            if piece.centre_words is not None:
                parts += [line.letter(letter) + t for letter, t in piece.centre_words]
            lines.append(sep.join(parts))
        if not out.arcs_modal:
            out.motion = linear
        return separator.join(lines)

    def _centre_in_place(self, words) -> None:
        """The first piece's centre words: numbers replaced where they change, R replaced by I J
        where R could not say the arc, missing offsets added after the last centre word."""
        line = self.line
        if words[0][0] != "R" and self.r_word is not None:
            line.replace_word(self.r_word, line.sep.join(line.letter(c) + t for c, t in words))
            return
        missing = []
        for letter, t in words:
            w = line.find(letter)
            if w is None:
                if float(t) != 0.0:
                    missing.append(line.letter(letter) + t)
            elif float(t) != float(line.number(w)):
                line.replace_number(w, t)
        line.insert_at(line.append_pos("XYZABCIJK"), missing)


def _line_ending(raw: bytes) -> str:
    if raw.endswith(b"\r\n"):
        return "\r\n"
    if raw.endswith(b"\n"):
        return "\n"
    return ""


def write_pass_through(f, raw: bytes, state: ModalState, out: OutputState, separator: str) -> None:
    """Write a non-motion line as it is; updates ``out``.

    Where the output is absolute while the input is incremental (after a G91 drilling cycle
    written absolute), a line whose axis words rely on G91 (G28/G30, an incremental move of an
    axis not known, G33.1) gets a line ``G91`` inserted before it. The output stands where the
    line leaves it: a known axis an incremental pass-through moves moves by the same increment
    from the output's position; an axis whose position the program loses is lost to the output
    too, and one the line gives again (G10 L20) reads what the program reads. An absolute arc
    from a position not given must start where the output stands uncorrected in its plane
    (:func:`.passed.check_passed_start`: InputError otherwise).
    """
    check_passed_start(state, out.values)
    if state.distance_sensitive and state.distance_word is None and state.incremental \
            and out.absolute:
        f.write(("G91" + (_line_ending(raw) or separator)).encode("latin-1"))
        out.absolute = False
    f.write(raw)
    if b"4" in raw:
        _cutter_comp(out, raw.decode("latin-1"))
    if state.frame_shift is not None:
        # G52 or a G10 of the active work system: the machine stays, the program's coordinates of
        # it move, and so do the output's (an incremental word after it starts from there)
        out.values += state.frame_shift
    if state.declared:
        # G92: the output's axes read the declared values too, wherever it stands
        out.values[state.declared] = state.position[state.declared]
    if state.distance_sensitive and state.incremental and not state.tapping:
        _follow_increments(raw, state, out)
    lost = ~state.known
    if lost.any():
        out.values[lost] = math.nan
    if state.had_g and (state.known & np.isnan(out.values)).any():
        _touched_off(raw, state, out)
    if state.distance_word == 91:
        out.absolute = False
    elif state.distance_word == 90:
        out.absolute = True
    if state.had_g:
        out.motion = state.motion if state.motion in (0, 1) and state.cycle is None else -1
    if state.ended and state.dialect.name == "grbl":     # its M2/M30 resets G1 G90 (dialect.py)
        out.absolute, out.motion = True, 1
    if state.passed_move is not None:
        why, line = state.passed_move
        out.passed_moves.setdefault(why, [0, line])[0] += 1
    if state.cycle_line:
        out.cycle_lines += 1
        passed_cycle(state, out)
        xi, yi, zi = state.xyz_index
        if state.cycle_start:
            out.cycle_init_z = out.values[zi]
        # the axis drilled along (Z in G17, Y in G18, X in G19) is not known after the line
        for i in (xi, yi, zi):
            out.values[i] = state.position[i] if state.known[i] else math.nan
        for attr in ("cycle_r", "cycle_z"):
            v = getattr(state, attr)
            setattr(out, attr, "" if v is None or v[1] else grid_text(v[0], False, state.inch))


def _follow_increments(raw: bytes, state: ModalState, out: OutputState) -> None:
    """An incremental move passed through: each known axis it names moves by its increment."""
    line = SourceLine(raw.decode("latin-1").rstrip("\r\n"))
    for i, c in enumerate(state.names):
        w = line.find(c)
        v = out.values[i]
        if w is None or not state.known[i] or v != v:
            continue
        out.values[i] = v + machine_units(float(line.number(w)), out.rotary[i], state.inch)


def _touched_off(raw: bytes, state: ModalState, out: OutputState) -> None:
    """A G10 L20 that gives the position of axes the output had lost: the output's own G10 L20
    (the line as written) makes them read the given values, as the program's do."""
    line = SourceLine(raw.decode("latin-1").rstrip("\r\n"))
    if not any(w[0] == "G" and float(line.number(w)) == 10 for w in line.words):
        return
    for i, c in enumerate(state.names):
        if state.known[i] and out.values[i] != out.values[i] and line.find(c) is not None:
            out.values[i] = state.position[i]


def write_corrected(in_path, out_path, machine: Machine, cursor: CorrectionCursor,
                    chord_tol_mm: float = DEFAULT_CHORD_TOL_MM, initial_position=None, *,
                    inch: bool = False, initial_known=None, stats: dict | None = None) -> int:
    """Pure-Python path of :func:`mtcomp.toolpaths.gcode.write_corrected`, which checks the output
    path and prepares the cursor over the corrections; returns the number of segment rows written."""
    kw = dict(inch=inch, initial_known=initial_known)
    letters = "".join(machine.axis_names)
    rotary = [c in "ABC" for c in letters]
    rows_written = 0
    out = None
    separator = "\n"
    with atomic_write(out_path, "wb") as f:
        for k, raw, block, state in iter_blocks(in_path, machine, chord_tol_mm, initial_position,
                                                **kw):
            if out is None:
                out = OutputState(machine.n_axes, new_state(machine, in_path, chord_tol_mm,
                                                            initial_position, **kw))
            if block is None:
                write_pass_through(f, raw, state, out, separator)
                continue
            pts = cursor.take(k, block.points.shape[0])
            ending = _line_ending(raw)
            separator = ending or separator
            text = format_motion_lines(block, pts, letters, rotary, out, ending, separator,
                                       raw.decode("latin-1").rstrip("\r\n"), chord_tol_mm,
                                       cursor.counts)
            rows_written += block.points.shape[0]
            f.write(text.encode("latin-1"))
        cursor.finish()
    if stats is not None:
        stats.update(writer_stats(out) if out is not None else {"cycle_lines": 0, "cycle_blocks": 0})
    return rows_written


def writer_stats(out: OutputState) -> dict:
    """What the writer counted (``stats`` of :func:`mtcomp.toolpaths.gcode.write_corrected`)."""
    stats = {"cycle_lines": out.cycle_lines, "cycle_blocks": out.cycle_blocks}
    if out.passed_moves:        # why -> (lines, first line)
        stats["passed_moves"] = {why: tuple(v) for why, v in out.passed_moves.items()}
    if out.cutter_arc_miss > 0:
        stats["cutter_arc_miss_mm"] = out.cutter_arc_miss
    if out.arc_miss > 0:
        stats["arc_miss_mm"] = out.arc_miss
    if out.added_lines:         # (lines, first line)
        stats["added_axis_words"] = (out.added_lines, out.added_line)
    return stats
