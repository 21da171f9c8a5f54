"""The segment ends of an NC program as the error maps read them, and the pairing of a program with
its compensated version (through the programs' line structure, or the compensation report's source
lines)."""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..machine import Machine


@dataclass
class ProgramPoints:
    """The segment end points of a program, in program order (all motion, rapids included).

    q : (n, na) axis positions, mm and rad. line : (n,) 1-based source lines. feed : (n,) mm/min
    (nan for rapids). dirs : (n, na) approach directions. rapid : (n,) bool. known : (n, na) bool, the
    program has given that axis's position (None: all). cycle : (n,) bool, the bottom of a hole of a
    drilling cycle (G73, G81-G89) (None: none). tcp : (n,) bool, a tool centre point block: its
    words were the tip and angles, ``q`` holds the axes the controller reaches (None: none).
    dialect : the controller's rules the program was read by (``--dialect``; None: detected).
    chord_tol_mm : the chord tolerance its arcs were read with (None: the reader's default).
    frames, local : the frames the program set itself (G52, G68, a mirror image, scaling:
    :func:`mtcomp.toolpaths.frames.placed_by_frames`'s table) and (n,) bool, the rows under one;
    ``q`` holds those rows placed where the controller puts them (None: no frame).
    tool : (n,) int, the tool length offset number (``G43 H``) in force at each row, 0 for none
    (None: not read). tool_names : the tools the program calls by name (a Sinumerik ``T="..."``)
    -> the number ``tool`` holds for each.
    machine_q : (n, na) where the machine's axes stand at each row, as compensate places the
    program (:meth:`mtcomp.toolpaths.offsets.ProgramSetup.apply`: the work offset in force, under
    Haas' G254 the part origin turned with the table, a tool centre point row's tip and angles
    turned into axes with the offset added to the tip); the model is evaluated there. datum : (n,
    na) the machine position of the part's datum (the program's origin as probed) at each row, the
    reference of the deviations. offsets : (n, na) the work offset of each row, as
    :meth:`~mtcomp.toolpaths.offsets.ProgramSetup.on_machine` takes it. setup : the set-up they
    were placed by. (None: not placed.)
    drawn : (n, na) the axis positions the map draws each row at (:func:`drawn_q`), where they
    differ from ``q``: under Haas' G254 the words are the tip relative to the part origin turned
    with the table, so the row is drawn where the tip is on the part (None: ``q``).
    """

    path: str
    q: np.ndarray
    line: np.ndarray
    feed: np.ndarray
    dirs: np.ndarray
    rapid: np.ndarray
    known: np.ndarray | None = None
    cycle: np.ndarray | None = None
    tcp: np.ndarray | None = None
    dialect: str | None = None
    chord_tol_mm: float | None = None
    frames: list | None = None
    local: np.ndarray | None = None
    tool: np.ndarray | None = None
    tool_names: dict | None = None
    machine_q: np.ndarray | None = None
    datum: np.ndarray | None = None
    offsets: np.ndarray | None = None
    setup: object = None
    drawn: np.ndarray | None = None

    def __len__(self):
        return int(self.line.shape[0])


def read_program_points(path, machine: Machine, dialect: str | None = None,
                        chord_tol_mm: float | None = None, setup=None) -> ProgramPoints:
    """Every segment end of the program at ``path`` (arcs as chords within ``chord_tol_mm``, None:
    the reader's default), read by the rules of ``dialect`` (None: detected from the program), and
    placed on the machine by ``setup`` (a :class:`~mtcomp.toolpaths.offsets.ProgramSetup`, as
    compensate was given it; None: no work offsets): ``machine_q``, ``datum``, ``offsets``.
    Raises InputError."""
    from ..toolpaths import SegmentChunk, iter_segment_chunks
    from ..toolpaths.offsets import ProgramSetup
    from ..toolpaths.source import open_program
    tol = {} if chord_tol_mm is None else {"chord_tol_mm": chord_tol_mm}
    setup = ProgramSetup(machine) if setup is None else setup
    with open_program(path, dialect, fixed_format=machine.fixed_format) as src:
        chunks = list(iter_segment_chunks(src, machine, **tol))
        frames = list(getattr(src, "local_frames", None) or [])
        names = dict(getattr(getattr(src, "sinumerik", None), "tool_names", None) or {})
        # compensate's placement of the blocks (one engine): the model is evaluated there
        placed = [setup.apply(c, src) for c in chunks]
    seg = SegmentChunk.concatenate(chunks, machine.n_axes)
    if len(seg.end) == 0:
        raise InputError("no motion block in the program: nothing to draw", path)
    q, local = _placed(seg, seg.end, frames, machine)
    # tool centre point rows: the words are the tip and the angles; the map is drawn from the axes
    # the controller reaches with the workpiece origin at the kinematics' own (the model is
    # evaluated at ``machine_q``), the approach directions are the axes' (compensate's), not the
    # tip words'
    from ..toolpaths.tcp import axes_of_tcp
    from ..toolpaths.words import frame_tcp, frame_tool
    tcp = frame_tcp(seg.frame) & seg.known.all(axis=1)
    if tcp.any():
        q[tcp] = axes_of_tcp(machine, q[tcp])
    machine_q, datum, dirs, offsets = (np.concatenate(v) for v in zip(
        *((m.end, m.datum, m.dirs, off) for m, off in placed)))
    return ProgramPoints(os.fspath(path), q, seg.line.copy(), seg.feed.copy(),
                         dirs, seg.rapid.copy(), seg.known.copy(), seg.cycle.copy(), tcp,
                         dialect, chord_tol_mm, frames if local.any() else None,
                         local if local.any() else None, np.asarray(frame_tool(seg.frame)).copy(),
                         names, machine_q, datum, offsets, setup,
                         _on_the_part(machine, q, seg, machine_q, datum))


def _on_the_part(machine: Machine, q: np.ndarray, seg, machine_q: np.ndarray,
                 datum: np.ndarray) -> np.ndarray | None:
    """The axis positions that draw each row under Haas' G254 (dynamic work offset) where its tip
    is on the part: the tip where compensate places it (``machine_q``, the offset turned with the
    table) less the part's datum, both in the table's frame, at the row's angles (None: no such
    row). Elsewhere the words are drawn as they are."""
    from ..kinematics import forward
    from ..toolpaths.tcp import axes_of_tcp
    from ..toolpaths.words import frame_dwo
    rows = frame_dwo(seg.frame) & seg.known.all(axis=1)
    if not rows.any():
        return None
    drawn = q.copy()
    words = q[rows].copy()
    xyz = [machine.index(c) for c in "XYZ"]
    words[:, xyz] = forward(machine, machine_q[rows])[0] - forward(machine, datum[rows])[0]
    drawn[rows] = axes_of_tcp(machine, words)
    return drawn


def drawn_q(orig: ProgramPoints) -> np.ndarray:
    """(n, na) the axis positions a map draws the program's rows at: the words (``q``), except
    where the program's words are not the tip on the part (``drawn``)."""
    return orig.q if orig.drawn is None else orig.drawn


def _placed(seg, pts, frames: list, machine: Machine) -> tuple[np.ndarray, np.ndarray]:
    """((n, na) the rows' positions ``pts`` (their ends or starts) in the work system, (n,) bool the
    rows under a frame): under a frame the program moved itself (G52, G68, a mirror image, scaling)
    its words placed where the controller puts them, so that the map and the pairing with the
    compensated program (read the same way) see the machine's positions."""
    from ..toolpaths.frames import placed_by_frames
    from ..toolpaths.words import frame_local
    local = frame_local(seg.frame)
    if not local.any():
        return pts.copy(), local
    return placed_by_frames(frames, local, seg.line, pts, [machine.index(c) for c in "XYZ"]), local


def _motion_runs(original: ProgramPoints, compensated: ProgramPoints) -> tuple[np.ndarray, np.ndarray]:
    """Run number of every segment end of both programs, from their line structure.

    The compensated program keeps every non-motion line of the original byte for byte and in order
    (mtcomp compensate writes it so); the motion lines between two such kept lines form a run, and
    a run of the original and the same run of the compensated program hold the same blocks, in the
    same order. Raises InputError where a kept line is missing."""
    def lines(path):
        # a program with code to compute is paired as the flat program it expands to (the lines
        # its segment ends are numbered by, and those compensate wrote with its corrections)
        from ..toolpaths.source import open_program
        with open_program(path, original.dialect) as src, open(src, "rb") as f:
            return f.read().split(b"\n")
    a, b = lines(original.path), lines(compensated.path)
    a_motion, b_motion = set(original.line.tolist()), set(compensated.line.tolist())
    run_a = np.zeros(len(a) + 2, np.int64)
    run_b = np.zeros(len(b) + 2, np.int64)
    j, run = 0, 0
    for k, raw in enumerate(a, 1):
        # a blank line bounds no run: a Heidenhain program's CC and cycle blocks read as blank
        # G-code lines, and compensate may add CC blocks among an arc's pieces
        if k in a_motion or not raw.strip():
            run_a[k] = run
            continue
        start = j
        while j < len(b) and ((j + 1) in b_motion or b[j] != raw):
            j += 1
        if j >= len(b):
            raise InputError(f"line {k} of {original.path} is not in the compensated program (is it "
                             "compensated from that program?)", compensated.path)
        run_b[start + 1:j + 1] = run
        run += 1
        j += 1
    run_b[j + 1:] = run
    return run_a[original.line], run_b[compensated.line]


def pair_compensated(original: ProgramPoints, compensated: ProgramPoints, machine: Machine,
                     tol_mm: float | None = None, tol_rad: float | None = None) -> np.ndarray:
    """For each segment end of ``original``, the index of its corrected counterpart in ``compensated``.

    Blocks are paired through the programs' line structure (:func:`_motion_runs`): within a run of
    motion lines, one to one when both have as many segment ends; else (the compensated program
    may split a move into pieces) by the monotone alignment that differs least (:func:`_aligned`). The pair must agree within a tolerance (default: four times the machine's
    largest correction, at least 0.05 mm / 50 urad). Raises InputError when the programs do not
    correspond.
    """
    comp = machine.compensation
    tol_mm = max(4e-3 * comp.get("max_correction_um", 50.0), 0.05) if tol_mm is None else tol_mm
    tol_rad = max(4e-6 * comp.get("max_correction_urad", 500.0), 5e-5) if tol_rad is None else tol_rad
    rotary = np.array([a.is_rotary for a in machine.axes])
    tol = np.where(rotary, tol_rad, tol_mm)
    n, m = len(original), len(compensated)
    idx = np.empty(n, np.int64)
    run_a, run_b = _motion_runs(original, compensated)
    for r in np.unique(run_a):
        ia = np.flatnonzero(run_a == r)
        ib = np.flatnonzero(run_b == r)
        if ib.size == 0:
            raise InputError(f"the compensated program has no motion where line "
                             f"{int(original.line[ia[0]])} of {original.path} moves",
                             compensated.path)
        if ia.size == ib.size:
            idx[ia] = ib
            continue
        if ib.size < ia.size:
            raise InputError(f"the compensated program has fewer moves than line "
                             f"{int(original.line[ia[0]])} of {original.path} and the lines after "
                             "it: not a compensated version of that program", compensated.path)
        idx[ia] = ib[_aligned(original.q[ia], compensated.q[ib], tol)]
    if n and m:
        diff = np.abs(compensated.q[idx] - original.q) > tol
        bad = np.flatnonzero(np.any(diff, axis=1))
        if bad.size:
            i = int(bad[0])
            d = np.abs(compensated.q[idx[i]] - original.q[i])
            what = ", ".join(f"{a} by {d[k] * (1e6 if rotary[k] else 1e3):.4g} "
                             f"{'urad' if rotary[k] else 'um'}"
                             for k, a in enumerate(machine.axis_names) if d[k] > tol[k])
            raise InputError(f"line {int(compensated.line[idx[i]])} differs from line "
                             f"{int(original.line[i])} of {original.path} ({what}): not a compensated "
                             "version of that program (or compensate was given another "
                             "--chord-tol-um: give render the same)", compensated.path)
    return idx


def _aligned(a: np.ndarray, b: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """For the ends ``a`` (n, na) of a run of the original, the indices into the compensated run's
    ends ``b`` (m, na), m >= n (a split block adds ends), increasing, that differ least in all (the
    sum over the run of each pair's largest difference in units of ``tol``): a monotone alignment
    by dynamic programming over how far ahead of its own place each original end is matched (ends
    a few um apart, as in a 5-axis program's short moves, would mislead a nearest match)."""
    n, m = a.shape[0], b.shape[0]
    slack = max(m - n, 0)
    if slack == 0:
        return np.arange(n)
    shift = np.arange(slack + 1)
    cost = np.empty((n, slack + 1))
    for i in range(n):
        j = np.minimum(i + shift, m - 1)
        cost[i] = np.max(np.abs(b[j] - a[i]) / tol, axis=1)
    total = cost[0].copy()
    back = np.zeros((n, slack + 1), np.int64)
    for i in range(1, n):
        # the shift never decreases: the best total over the shifts up to each one
        best = np.minimum.accumulate(total)
        before = np.concatenate([[np.inf], best[:-1]])
        back[i] = np.maximum.accumulate(np.where(total < before, shift, 0))
        total = best + cost[i]
    d = int(np.argmin(total))
    out = np.empty(n, np.int64)
    for i in range(n - 1, -1, -1):
        out[i] = i + d
        d = int(back[i, d])
    return out


def _source_lines(original: ProgramPoints) -> np.ndarray:
    """(n,) the source line of each segment end: its line, or for a program with code to compute
    the line of the user's file its expanded line came from (the compensation report's ``line``)."""
    from ..toolpaths.source import open_program
    with open_program(original.path, original.dialect) as src:
        return src.source_lines_of(original.line)


def report_points(original: ProgramPoints, report, machine: Machine) -> ProgramPoints:
    """The corrected positions of the original's segment ends, from the BLOCKS.csv of
    ``mtcomp compensate`` (its rows that are not inserted nodes, in order, by source line)."""
    import csv
    path = os.fspath(report)
    cols = [f"{a.lower()}_deg" if a in "ABC" else f"{a.lower()}_mm" for a in machine.axis_names]
    try:
        with open(path, newline="") as f:
            rows = [r for r in csv.DictReader(f) if r.get("inserted", "0") == "0"]
    except FileNotFoundError:
        raise InputError("no such report file", path) from None
    if len(rows) != len(original):
        raise InputError(f"the report has {len(rows)} blocks, the program {len(original)} segment "
                         "ends: not the report of that program (or compensate was given another "
                         "--chord-tol-um: give render the same)", path)
    try:
        # a blank cell: an axis the program had not positioned there, which the block leaves alone
        q = np.array([[float(r[c]) if r[c] != "" else np.nan for c in cols] for r in rows])
        line = np.array([int(r["line"]) for r in rows])
    except (KeyError, ValueError, TypeError):
        raise InputError(f"not a report of mtcomp compensate (columns line, inserted, "
                         f"{', '.join(cols)})", path) from None
    q[:, [a.is_rotary for a in machine.axes]] = np.radians(q[:, [a.is_rotary for a in machine.axes]])
    blank = np.isnan(q)
    if original.local is not None:
        # the report gives a block's words; under a frame the program set, placed as the program's
        from ..toolpaths.frames import placed_by_frames
        q = placed_by_frames(original.frames, original.local, original.line, np.where(blank, 0.0, q),
                             [machine.index(c) for c in "XYZ"])
    # a blank cell: the program's own position (placed; a tool centre point row has none blank)
    words = np.where(blank, original.q, q)
    program_line = _source_lines(original)
    bad = np.flatnonzero(line != program_line)
    if bad.size:
        raise InputError(f"row {int(bad[0]) + 2} is for line {int(line[bad[0]])}, the program's "
                         f"segment end there is on line {int(program_line[bad[0]])}", path)
    # the report holds the words written (a tool centre point block's: the tip and angles), placed
    # on the machine as compensate placed the program's (the same work offsets, per row)
    tcp = np.zeros(len(original), bool) if original.tcp is None else original.tcp
    q = words.copy()
    if tcp.any():
        from ..toolpaths.tcp import axes_of_tcp
        q[tcp] = axes_of_tcp(machine, q[tcp])
    machine_q = None if original.offsets is None else \
        original.setup.on_machine(words, original.offsets, tcp)
    return ProgramPoints(path, q, line, original.feed, original.dirs, original.rapid,
                         machine_q=machine_q, datum=original.datum, offsets=original.offsets,
                         setup=original.setup)

