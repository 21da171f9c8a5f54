"""The residual the planner drives to zero, and its Jacobian, in optimisation units.

For a block with nominal axis positions q (mm, rad) and context c, and a correction x (um for linear
axes, urad for rotary axes; dq = x / axis_scale):

    r(x) = actual_pose(q + dq, c) - nominal_pose(q)
         = nominal(q + dq) + deviation(q + dq, c) - nominal(q)

(tip rows in mm; on 5-axis machines also the tool-axis rows), returned weighted: ``b = S r`` with S
from :attr:`CompensationProblem.residual_scale` (um, and urad times the orientation weight), and the
Jacobian ``A = S (J_nominal + J_q) / axis_scale`` (weighted residual per um or urad of correction).

What the methods minimise is not ``|b|^2`` itself: on 5-axis machines the tool-axis rows enter the
objective as ``M e`` (:meth:`Evaluator.orientation_rows`, :func:`objective_residual`), the part of the
tool-axis deviation e the rotary axes can turn the tool against at that block (see
``CompensationProblem.orientation_damping``). ``b`` and ``A`` themselves stay the deviation as it is,
which is what the report shows.
"""
from __future__ import annotations

import threading

import numpy as np

from ..kinematics import forward as nominal_pose
from ..kinematics import pose_jacobian as nominal_pose_jacobian
from ..models.evaluate import evaluate
from ..models.assumed import Assumed
from ._small import any_rows, down_columns
from ._uncertainty import CorrectionUncertainty, split_hold
from .problem import CompensationProblem


def objective_residual(M: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, rows): the residual b (n, rows) as the objective counts it, its tool-axis rows 3:6 replaced
    by ``M e`` (M (n, 3, 3) from :meth:`Evaluator.orientation_rows`); b itself on 3-axis machines
    (M (n, 0, 0))."""
    if M.shape[1] == 0:
        return b
    out = np.array(b, copy=True)
    e = b[:, 3:6]
    for k in range(3):
        out[:, 3 + k] = M[:, k, 0] * e[:, 0] + M[:, k, 1] * e[:, 1] + M[:, k, 2] * e[:, 2]
    return out


def objective_jacobian(M: np.ndarray, A: np.ndarray) -> np.ndarray:
    """(n, rows, na): the Jacobian A (n, rows, na) of :func:`objective_residual`'s rows (M is
    constant)."""
    if M.shape[1] == 0:
        return A
    out = np.array(A, copy=True)
    for k in range(3):
        out[:, 3 + k, :] = (M[:, k, 0, None] * A[:, 3, :] + M[:, k, 1, None] * A[:, 4, :]
                            + M[:, k, 2, None] * A[:, 5, :])
    return out


def _run_starts(a: np.ndarray) -> np.ndarray:
    """(n,) bool: the rows of ``a`` (n, ...) that differ from the row before (the first row too)."""
    n = a.shape[0]
    new_run = np.ones(n, bool)
    if n > 1:
        new_run[1:] = any_rows(a[1:] != a[:-1])
    return new_run


def _unique_runs(first_rows: np.ndarray, new_run: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_unique_rows` from the first row of each run (``first_rows``, in order) and where the
    runs start (``new_run`` (n,) bool)."""
    uniq, inv = np.unique(first_rows, axis=0, return_inverse=True)
    return uniq, inv.reshape(-1)[np.cumsum(new_run) - 1]


def _unique_rows(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the distinct rows of ``a`` (n, k) in sorted order, (n,) the index of each row's among them):
    ``np.unique(a, axis=0, return_inverse=True)``, sorting only the first row of each run of equal
    rows (a program's datum and tool length change a few times in a million blocks; sorting every
    row took a third of a compensation)."""
    new_run = _run_starts(a)
    return _unique_runs(a[new_run], new_run)


#: poses whose parameter Jacobians :meth:`Evaluator.correction_sd_assumed` evaluates and reduces at
#: once: about 7 MB of Jacobian at 274 parameters (a few copies of it a planner thread), and one
#: matrix product of 3 x this many rows
SD_ROWS = 1024


class Evaluator:
    """Residuals and Jacobians of one problem, vectorised over blocks."""

    def __init__(self, problem: CompensationProblem):
        self.problem = problem
        self.model = problem.fitted.model
        self.p = np.asarray(problem.fitted.params.values, dtype=float)
        self.machine = problem.machine
        self.rows = 6 if problem.correct_orientation else 3
        self.S = problem.residual_scale
        self.D = problem.axis_scale
        self.evaluations = 0
        self._count_lock = threading.Lock()     # parts of a chunk are evaluated in threads
        #: a correction's standard error, as export's tables and render's map take it
        self.uncertainty = CorrectionUncertainty(problem.fitted)
        #: the model carries a covariance: :meth:`correction_sd_assumed` is NaN everywhere without one
        self.has_uncertainty = self.uncertainty.known
        #: (function name, datum row, tool length) -> the function there (:meth:`_at_datum`)
        self._datum_values: dict = {}
        #: why some corrections' standard errors were infinite (:meth:`_note_causes`)
        self.infinite_causes: set = set()
        #: what the model's corrections assume at zero (None: nothing), :mod:`._assumed`
        self.assumed = Assumed.of(problem.fitted, problem.machine)

    def _count(self, n: int):
        with self._count_lock:
            self.evaluations += n

    def _deviation(self, q, ctx):
        """(n, 6) the model's deviation at q, evaluated at the held position of every axis the
        model's data held still (FittedModel.clamp)."""
        return evaluate(self.model, "deviation_function", self.problem.fitted.clamp(q)[0], self.p, ctx)[0]

    @property
    def axis_columns(self) -> int:
        """3 on 5-axis machines (the tool axis's standard errors follow the tip's in
        :meth:`correction_sd_assumed`), else 0."""
        return 3 if self.rows == 6 else 0

    def correction_sd_assumed(self, q, ctx, datum=None, sd: bool = True) -> np.ndarray:
        """(n, 3 + k + Assumed.width): each tip component's standard error (um) of the correction at
        q (NaN where not ``sd``): the tip deviation less the deviation at the part's datum, as
        :meth:`datum_reference` takes it, when ``datum`` (n, na) is given, evaluated where
        :meth:`_deviation` evaluates it (:meth:`CorrectionUncertainty.components`: infinite where
        the correction moves with values the data left undetermined); NaN when the model carries
        no uncertainty. On 5-axis machines (k = :attr:`axis_columns`) each tool-axis component's
        (urad, :meth:`CorrectionUncertainty.orientation`: the deviation as it stands, not
        referenced). Then, when the model assumes something at zero (:attr:`assumed`),
        :meth:`Assumed.blocks` of the same Jacobian. The correction in its standard errors is
        :func:`._uncertainty.in_sd` of the correction the plan evaluates anyway (its ``b0``)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        k = self.axis_columns
        out = np.full((q.shape[0], 3 + k + (self.assumed.width if self.assumed else 0)), np.nan)
        if not self.has_uncertainty:
            return out
        # in parts of SD_ROWS poses: the Jacobians of a spline model (3 x 274 numbers a pose) of a
        # whole chunk of a program took a gigabyte
        for lo in range(0, q.shape[0], SD_ROWS):
            part = slice(lo, lo + SD_ROWS)
            self._sd_assumed_part(out[part], q[part], ctx[part],
                                  None if datum is None else datum[part], sd)
        return out

    def _sd_assumed_part(self, out, q, ctx, datum, sd: bool) -> None:
        """:meth:`correction_sd_assumed` of some poses, written into ``out``."""
        qc = self.problem.fitted.clamp(q)[0]
        J = evaluate(self.model, "tip_pjacobian_function", qc, self.p, ctx)[0]
        J0 = None if datum is None else self._at_datum("tip_pjacobian_function", datum, ctx)
        if sd:
            out[:, :3] = self.uncertainty.components(J, J0)
        if J0 is not None and (sd or self.assumed):
            J = J - J0
        k = self.axis_columns
        if sd:
            self._note_causes(J, out[:, :3])
            if k:
                Ja = evaluate(self.model, "axis_pjacobian_function", qc, self.p, ctx)[0]
                out[:, 3:6] = self.uncertainty.orientation(Ja)
        if self.assumed:
            out[:, 3 + k:] = self.assumed.blocks(q, J)

    def _note_causes(self, J, each) -> None:
        """Add to :attr:`infinite_causes` why some of the standard errors ``each`` (n, 3) of the
        tip deviations of Jacobian J are infinite: ``"undetermined"`` where the deviation moves
        with values the data left undetermined (MODEL.json ``uncertainty.undetermined``),
        ``"choice"`` where it rests on the penalty's split of what the data cannot tell apart
        (``uncertainty.choice``) and not on undetermined values."""
        inf = np.isinf(each).any(axis=1)
        if not inf.any() or self.infinite_causes >= {"undetermined", "choice"}:
            return
        found = set()
        u = self.uncertainty
        if u.choice is None:
            found.add("undetermined")
        elif u.open is None:
            found.add("choice")
        else:
            alone = np.isinf(self.problem.fitted.tip_sd_um(J[inf], u.factor, u.open))
            if alone.any():
                found.add("undetermined")
            if not alone.all():
                found.add("choice")
        with self._count_lock:
            self.infinite_causes |= found

    def correction_um(self, q, ctx, datum=None) -> np.ndarray:
        """(n, 3) um: the correction at q, the tip deviation less that at the part's datum
        (:meth:`datum_reference`; None: the raw deviation), as the plan's ``b0`` holds it."""
        dev = self._deviation(q, ctx)[:, :3]
        if datum is not None:
            dev = dev - self._at_datum("deviation_function", datum, ctx)[:, :3]
        return dev * 1e3

    def _deviation_and_qjacobian(self, q, ctx):
        """(deviation (n, 6), d deviation / d q (n, 6, n_axes)) as :meth:`_deviation`: along a held
        axis the deviation does not change."""
        qc, held = self.problem.fitted.clamp(q)
        dev, Jd = evaluate(self.model, "deviation_qjacobian_function", qc, self.p, ctx)
        if held:
            Jd = np.array(Jd, copy=True)
            Jd[:, :, held] = 0.0
        return dev, Jd

    def orientation_rows(self, q: np.ndarray, nominal_jacobian: np.ndarray | None = None) -> np.ndarray:
        """(n, 3, 3) M with ``M^T M = W = J (J^T J + d^2 I)^-1 J^T``: the objective counts the
        tool-axis rows e of a block's residual as ``|M e|^2 = e^T W e``; (n, 0, 0) on 3-axis machines.

        J (3, n_rotary) is the nominal tool axis's Jacobian with respect to the rotary axes at the
        nominal position q (n, n_axes; mm, rad), d ``CompensationProblem.orientation_damping``. In J's
        singular directions W weighs a deviation by sigma^2 / (sigma^2 + d^2): 1 where the rotary axes
        turn the tool well, 0 where they cannot turn it at all (the tool axis parallel to a turntable,
        and the tool axis's own direction). Without this, a deviation no rotary axis can remove
        (at tilt 0 on a CA table, the X component) drew large rotary corrections through the model's
        tiny second-order sensitivities (1e-4 urad per urad), paid for with X/Y at their bounds.
        M depends on the nominal pose only, so every method and iteration minimises the same thing.
        nominal_jacobian : (n, 6, n_axes) the nominal pose's Jacobian at q when already computed.
        """
        q = np.asarray(q, dtype=float)
        n = q.shape[0]
        if self.rows == 3:
            return np.zeros((n, 0, 0))
        if nominal_jacobian is None:
            nominal_jacobian = nominal_pose_jacobian(self.machine, q)[2]
        rot = [j for j, a in enumerate(self.machine.axes) if a.is_rotary]
        d2 = self.problem.orientation_damping ** 2
        M = np.zeros((n, 3, 3))
        # W = J G^-1 J^T = (L^-1 J^T)^T (L^-1 J^T) with G = J^T J + d^2 I = L L^T; entry by entry
        # on (n,) vectors for the usual two rotary axes (a batched Cholesky costs ten times more)
        if len(rot) == 2:
            u, v = nominal_jacobian[:, 3:6, rot[0]], nominal_jacobian[:, 3:6, rot[1]]  # (n, 3)
            l11 = np.sqrt(np.einsum("ni,ni->n", u, u) + d2)
            l21 = np.einsum("ni,ni->n", u, v) / l11
            l22 = np.sqrt(np.einsum("ni,ni->n", v, v) + d2 - l21 * l21)
            M[:, 0, :] = u / l11[:, None]
            M[:, 1, :] = (v - l21[:, None] * M[:, 0, :]) / l22[:, None]
            return M
        J = nominal_jacobian[:, 3:6, rot]                                     # (n, 3, k) rad / rad
        G = np.einsum("nik,nil->nkl", J, J) + d2 * np.eye(len(rot))
        M[:, :len(rot), :] = np.linalg.solve(np.linalg.cholesky(G), np.swapaxes(J, 1, 2))
        return M

    def target_and_orientation_rows(self, q: np.ndarray):
        """(target (n, rows), orientation_rows (n, 3, 3) or (n, 0, 0)) of q: :meth:`target` and
        :meth:`orientation_rows` from one evaluation of the nominal kinematics."""
        q = np.asarray(q, dtype=float)
        if self.rows == 3:
            return self.target(q), np.zeros((q.shape[0], 0, 0))
        tip, axis, Jn = nominal_pose_jacobian(self.machine, q)
        return np.concatenate([tip, axis], axis=1), self.orientation_rows(q, Jn)

    def target(self, q: np.ndarray) -> np.ndarray:
        """(n, rows) nominal pose (tip mm, tool axis) of q: what the program means."""
        if self.rows == 3 and not self.machine.rotary_axes:
            # the tip alone: the pose with its (constant, read-only) Jacobian, no copy of the axis
            return nominal_pose_jacobian(self.machine, q)[0]
        tip, axis = nominal_pose(self.machine, q)
        return tip if self.rows == 3 else np.concatenate([tip, axis], axis=1)

    def residual_jacobian_rows(self, q, ctx, reference=None):
        """(b, A, target, orientation_rows, held) of the uncorrected blocks (x = 0): one nominal
        Jacobian for both. ``reference`` (n, rows): what the target takes beside the nominal pose,
        the deviation at the part's datum (:meth:`datum_reference`); None: nothing; with three
        more columns (:func:`._uncertainty.with_hold`), the tip components whose deviation the
        solve holds: their target is the uncorrected pose, so the solve keeps their deviation;
        ``held`` (n, rows) the weighted residual the target took that way (zero elsewhere):
        ``b + held`` is the deviation less the datum's."""
        b, A, target, Jn = self.residual_jacobian(q, None, ctx, _with_nominal=True)
        held = np.zeros(b.shape)
        if reference is not None:
            reference, hold = split_hold(reference, self.rows)
            target = down_columns(np.add, target, reference)
            b = b - down_columns(np.multiply, reference, self.S)
            if hold is not None:
                held[:, :3] = np.where(hold, b[:, :3], 0.0)
                b = b - held
                target = target + held / self.S
        return b, A, target, self.orientation_rows(q, Jn), held

    def datum_reference(self, datum, ctx) -> np.ndarray:
        """(n, rows): the model's tip deviation at the part's datum (machine positions (n, na) of the
        program's origin) as the machinist probed it (FittedModel.datum_deviation: the block's tool
        length, the model's reference conditions otherwise, no thermal drift, as export's tables
        take their reference; a drift while the program runs is corrected), zero tool-axis rows.
        This much of every block's deviation is already in the probed offset: a block's correction
        removes its deviation less this (what a laser's zero or a constant left open cannot
        change). Evaluated once per distinct datum and tool length; one row broadcast (read-only)
        over the blocks when they all share it (the usual case: no (n, rows) copies)."""
        datum = np.atleast_2d(np.asarray(datum, dtype=float))
        dev = self._at_datum("deviation_function", datum, ctx)
        if dev.strides[0] == 0 and dev.shape[0] > 1:
            row = np.zeros(self.rows)
            row[:3] = dev[0, :3]
            return np.broadcast_to(row, (datum.shape[0], self.rows))
        out = np.zeros((datum.shape[0], self.rows))
        out[:, :3] = dev[:, :3]
        return out

    def _at_datum(self, name: str, datum, ctx) -> np.ndarray:
        """The model's function ``name`` at each block's datum in the datum's context, evaluated once
        per distinct (datum, tool length): a program has one datum or a few (one: its value
        broadcast over the blocks, read-only)."""
        ctx = np.atleast_2d(ctx)
        names = self.model.context_names
        tool = ctx[:, names.index("tool_length")] if "tool_length" in names else np.zeros(ctx.shape[0])
        # the runs of equal (datum, tool length) found on each apart: no (n, k + 1) copy of them
        new_run = _run_starts(datum)
        new_run |= _run_starts(tool)
        firsts = np.flatnonzero(new_run)
        if firsts.size == 1:
            # the program's one datum and tool: evaluated once, not once a chunk
            key = (name, datum[0].tobytes(), np.float64(tool[0]).tobytes())
            value = self._datum_values.get(key)
            if value is None:
                value = self._datum_values[key] = self.problem.fitted.at_datum(name, datum[:1],
                                                                               tool[:1])
            return np.broadcast_to(value[0], (datum.shape[0],) + value.shape[1:])
        uniq, inv = _unique_runs(np.column_stack([datum[firsts], tool[firsts]]), new_run)
        return self.problem.fitted.at_datum(name, uniq[:, :-1], uniq[:, -1])[inv]

    def residual_jacobian(self, q, x, ctx, target=None, _with_nominal=False):
        """Weighted residual b (n, rows) and Jacobian A (n, rows, n_axes) at corrections x (n, n_axes)
        (None: zero).

        Returns (b, A, target): target (n, rows) is computed when not given (at x = 0 it is free).
        """
        q = np.asarray(q, dtype=float)
        zero = x is None or not np.any(x)
        qq = q if zero else q + down_columns(np.divide, x, self.D)
        dev, Jd = self._deviation_and_qjacobian(qq, ctx)
        tip, axis, Jn = nominal_pose_jacobian(self.machine, qq)
        self._count(q.shape[0])
        rows = self.rows
        if target is None:
            target = (tip if rows == 3 else np.concatenate([tip, axis], axis=1)) if zero \
                else self.target(q)
        r = down_columns(np.add, dev[:, :rows], tip) if rows == 3 \
            else dev + np.concatenate([tip, axis], axis=1)
        r -= target
        down_columns(np.multiply, r, self.S, out=r)
        # stored entry by entry, (rows, n_axes, n) contiguous, returned as its (n, rows, n_axes)
        # view: every entry is one contiguous vector (as NormalFactor and a_x read them)
        na = Jd.shape[2]
        scale = self.S[:, None] / self.D[None, :]
        Jt = np.empty((rows, na, q.shape[0]))
        if Jn.shape[0] > 1 and Jn.strides[0] == 0:
            Jn_ij = Jn[0]       # one Jacobian broadcast (no rotary axis): its entries as numbers
        else:
            Jn_ij = Jn.transpose(1, 2, 0)
        for i in range(rows):
            for j in range(na):
                np.add(Jd[:, i, j], Jn_ij[i, j], out=Jt[i, j])
                if scale[i, j] != 1.0:
                    Jt[i, j] *= scale[i, j]
        if _with_nominal:
            return r, Jt.transpose(2, 0, 1), target, Jn
        return r, Jt.transpose(2, 0, 1), target

    def residual(self, q, x, ctx, target):
        """Weighted residual b (n, rows) only (cheaper: no Jacobian of the model)."""
        q = np.asarray(q, dtype=float)
        qq = q + down_columns(np.divide, x, self.D)
        dev = self._deviation(qq, ctx)
        self._count(q.shape[0])
        r = down_columns(np.add, dev[:, :self.rows], self.target(qq))
        r -= target
        return down_columns(np.multiply, r, self.S, out=r)

    def tool_point(self, q, ctx, along=None) -> np.ndarray:
        """(n, 3) mm, workpiece frame: where the model puts the point ``along`` (n,) mm up the tool
        axis from the tip (None: the tip) with the axes at q (n, na) in the context ``ctx``: the
        nominal pose plus the model's tip and tool-axis deviation, evaluated as the residual
        evaluates it (:meth:`_deviation`). The error maps' deviation: this at a block's corrected
        (or own) position, less the nominal point at its own position and the deviation at the
        part's datum (:meth:`datum_reference`), is the residual the plan left there."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        dev = self._deviation(q, ctx)
        tip, axis = nominal_pose(self.machine, q)
        out = tip + dev[:, :3]
        if along is not None:
            out += np.asarray(along, dtype=float)[:, None] * (axis + dev[:, 3:6])
        return out

    def deviation_only(self, q, ctx):
        """Weighted model deviation (n, rows) at q (the residual of the uncorrected program)."""
        dev = self._deviation(q, ctx)
        return dev[:, :self.rows] * self.S
