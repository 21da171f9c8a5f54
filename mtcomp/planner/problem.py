"""The compensation problem (what to solve) and the planner options (how to solve it).

Kept apart on purpose, like acados' ``AcadosOcp`` and ``AcadosOcpSolver``: a
:class:`CompensationProblem` describes costs, bounds and the output grid; :class:`PlannerOptions`
say which method runs it, in what windows and to what tolerance.

Units: the problem stores everything in the internal units (mm and rad). Its constructor
:meth:`CompensationProblem.from_machine` takes the file units of the machine file and command line
(um, urad) and converts them once. Inside the optimisation the corrections are scaled to um (linear
axes) and urad (rotary axes), the tip deviation to um and the tool-axis deviation to urad times
``orientation_weight``; see docs/planner.md.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..machine import Machine
from ..models.model_file import FittedModel

#: a block whose correction's standard error exceeds this (um) is left uncorrected, and export
#: writes no table for an axis where it does: the model is unsure there (a profile bridged by the
#: penalty over a gap, a tool length far from the measured ones, a ballbar circle alone, laser runs
#: that drift from run to run). Set from real laser runs (docs/planner.md, *Blocks where the model
#: is unsure*): models of stages whose runs repeat reach 0.2 to 4.3 um over their travel (but
#: identify's of one stage with two glitch readings, 6.7 um), those of runs drifting by 12.7 um
#: (diagnose's) 5.7 um, by up to 100 um 6.2 to 17.5 um, one ballbar circle's least squares
#: thousands (diagnose writes identify's penalised fit, never the least squares)
DEFAULT_MAX_CORRECTION_SD_UM = 5.0


#: why a standard error is infinite (FittedModel.tip_sd_um), as unsure_advice says it
_INFINITE = {
    "undetermined": "values of the model that its data did not determine (MODEL.json's "
                    "uncertainty.undetermined; identify holds those at zero)",
    "choice": "how the fit's roughness penalty split between kinds of error what the data cannot "
              "tell apart (MODEL.json's uncertainty.choice: the split is the penalty's choice, not "
              "a reading; e.g. a rotary axis's error motions read at one height or one radius)"}


def unsure_advice(largest_sd_um: float, limit_um: float, what: str = "corrects them",
                  causes=("undetermined",)) -> str:
    """What to do about corrections left out for their standard error: a larger limit where it is
    near the limit; where it is far beyond (10 times), only more data (a ballbar circle alone leaves
    the axes' profiles at standard errors of thousands of um: a larger limit would write them).
    An infinite standard error: the correction moves with values of the model that its data did not
    determine, or rests on the penalty's split of what they cannot tell apart (``causes``, of
    ``"undetermined"`` and ``"choice"``: :meth:`mtcomp.models.model_file.FittedModel.tip_sd_um`)."""
    if not largest_sd_um < float("inf"):
        said = " and some on ".join(_INFINITE[c] for c in ("undetermined", "choice") if c in causes)
        return (f"some rest on {said or _INFINITE['undetermined']}: measure there, or fit the "
                "model again; no finite --max-correction-sd-um writes them, only 0 (no limit), "
                "with corrections that rest on what nothing measured")
    if largest_sd_um > 10.0 * limit_um:
        return (f"the data do not determine them (a standard error {largest_sd_um / limit_um:.0f} "
                "times the limit): measure there (laser runs along the axes, ballbar circles in "
                "more planes and radii); a larger --max-correction-sd-um would write corrections "
                "that rest on what nothing measured")
    return f"more data there, or a larger --max-correction-sd-um, {what}"

METHODS = ("qp", "pinv", "newton")
#: output resolution (docs/toolpaths.md): 4 decimals of mm and deg; 5 decimals of inch
MM_GRID = 1e-4
DEG_GRID = 1e-4
INCH_GRID_MM = 25.4e-5


def output_grid(machine: Machine, inch: bool = False) -> np.ndarray:
    """(n_axes,) the resolution of written coordinates: mm for linear, rad for rotary axes."""
    return np.array([math.radians(DEG_GRID) if a.is_rotary else (INCH_GRID_MM if inch else MM_GRID)
                     for a in machine.axes])


@dataclass(frozen=True)
class CompensationProblem:
    """A compensation problem: model, bounds, weights, output grid.

    fitted : the error model with its parameters (MODEL.json). Its machine supplies travel and tool length.
    max_correction : (n_axes,) largest correction per block, mm (linear axes) and rad (rotary axes).
    max_step : (n_axes,) largest change of a correction between consecutive output blocks, mm / rad.
    orientation_weight : um of tool-tip deviation that weigh as much as 1 urad of tool-axis deviation
        (5-axis machines only; 3-axis machines cannot correct orientation and ignore it). Default 1.
    orientation_damping : urad of tool-axis turn per urad of rotary correction (dimensionless, > 0)
        below which a direction of the tool-axis deviation progressively drops out of the objective.
        The tool-axis deviation e counts as ``e^T W e`` with ``W = J (J^T J + d^2 I)^-1 J^T``, J the
        nominal tool axis's Jacobian with respect to the rotary axes at the block (d this damping):
        a direction in which the rotary axes turn the tool by sigma per unit counts with weight
        ``sigma^2 / (sigma^2 + d^2)``, so fully where they reach it (tilt 30 deg: 0.998), not at all
        where they cannot (tilt 0: the tool axis parallel to the turntable's axis, where only a B
        axis could remove a deviation in X). Default 0.02 (a tilt of about 1.1 deg weighs 1/2).
    regularization : weight (per um^2 of linear correction) of a small penalty on the corrections
        that makes the problem strictly convex. Default 1e-6: it changes a 50 um correction by ~5e-5 um.
    rotary_regularization : the same per urad^2 of rotary correction. Default 1e-5 (1 urad weighs
        like 3.2 um): where a tip error can be removed by the linear axes or by turning a table that
        moves the tip r um per urad (r: the tip's distance from the table axis in m), the table takes
        the share r^2 / (r^2 + 10) of it (1.6 % at 0.4 m) instead of r^2 / (r^2 + 1) (14 %), so that
        a table is not turned where only the linear axes need to move (tilt 0 on a CA table). Where
        the rotary axes turn the tool by sigma urad per urad it leaves 1e-5 / sigma^2 of a tool-axis
        correction undone (4e-5 at a tilt of 30 deg: 0.004 urad of 100).
    step_across_rapids : False (default): the step bound does not apply into the end of a G0 move
        (no cutting happens during a rapid, so the correction may jump there). True: it applies
        between every pair of consecutive output blocks.
    grid : (n_axes,) resolution of the written coordinates (mm, rad) or None. With a grid the nominal
        positions are first rounded to it (the program as it would be written uncorrected) and the
        written corrections are whole multiples of it, so every bound holds exactly in the output.
    """

    fitted: FittedModel
    max_correction: np.ndarray
    max_step: np.ndarray
    orientation_weight: float = 1.0
    regularization: float = 1e-6
    step_across_rapids: bool = False
    grid: np.ndarray | None = None
    orientation_damping: float = 0.02
    rotary_regularization: float = 1e-5

    def __post_init__(self):
        for name in ("orientation_damping", "regularization", "rotary_regularization"):
            v = getattr(self, name)
            if isinstance(v, bool) or not math.isfinite(v) or v <= 0:
                raise InputError(f"{name} must be a positive number, got {v!r}")

    @property
    def machine(self) -> Machine:
        return self.fitted.machine

    @property
    def n_axes(self) -> int:
        return self.machine.n_axes

    @property
    def correct_orientation(self) -> bool:
        """True on machines with rotary axes: the tool axis is part of the objective."""
        return self.machine.is_five_axis

    @property
    def regularization_weights(self) -> np.ndarray:
        """(n_axes,) weight of the penalty per um^2 (linear axes) or urad^2 (rotary axes)."""
        return np.array([self.rotary_regularization if a.is_rotary else self.regularization
                         for a in self.machine.axes])

    @property
    def axis_scale(self) -> np.ndarray:
        """(n_axes,) internal unit -> optimisation unit: 1e3 (mm -> um), 1e6 (rad -> urad)."""
        return np.array([1e6 if a.is_rotary else 1e3 for a in self.machine.axes])

    @property
    def residual_scale(self) -> np.ndarray:
        """(3,) or (6,): tip mm -> um, tool axis -> urad times orientation_weight."""
        s = [1e3] * 3
        if self.correct_orientation:
            s += [1e6 * self.orientation_weight] * 3
        return np.array(s)

    @classmethod
    def from_machine(cls, fitted: FittedModel, max_correction_um: float | None = None,
                     max_correction_urad: float | None = None, max_step_um: float | None = None,
                     max_step_urad: float | None = None, grid: np.ndarray | None = None,
                     **kwargs) -> "CompensationProblem":
        """Bounds from the machine's [compensation] table, overridden by the values given (um, urad).

        max_step_urad defaults to max_step_um scaled like the corrections:
        ``max_step_um / max_correction_um * max_correction_urad`` (5 / 50 * 500 = 50 urad).
        """
        comp = fitted.machine.compensation
        mc_um = comp["max_correction_um"] if max_correction_um is None else max_correction_um
        mc_urad = comp["max_correction_urad"] if max_correction_urad is None else max_correction_urad
        ms_um = comp["max_step_um"] if max_step_um is None else max_step_um
        # max_correction_urad may be 0: the rotary axes are never corrected
        for name, v in (("max_correction_um", mc_um), ("max_correction_urad", mc_urad),
                        ("max_step_um", ms_um), ("max_step_urad", max_step_urad)):
            if v is not None and (isinstance(v, bool) or not math.isfinite(v) or v < 0
                                  or (v == 0 and name != "max_correction_urad")):
                raise InputError(f"{name} must be a positive number, got {v!r}")
        ms_urad = ms_um / mc_um * mc_urad if max_step_urad is None else max_step_urad
        axes = fitted.machine.axes
        # a rotary axis the model's data held at one angle gets no correction: nothing says how the
        # errors change as it turns, and what it would correct (the tool's orientation) one angle's
        # data hardly fix
        held = fitted.held or {}
        max_corr = np.array([(0.0 if a.name in held else mc_urad * 1e-6) if a.is_rotary else mc_um * 1e-3
                             for a in axes])
        max_step = np.array([ms_urad * 1e-6 if a.is_rotary else ms_um * 1e-3 for a in axes])
        return cls(fitted, max_corr, max_step, grid=grid, **kwargs)

    def travel(self) -> tuple[np.ndarray, np.ndarray]:
        return self.machine.travel_bounds()


@dataclass(frozen=True)
class PlannerOptions:
    """How to solve a :class:`CompensationProblem`.

    method : 'qp' (default: bounded optimisation over the whole program, OSQP in windows), 'pinv'
        (Qi and Yang (2016), eqs. 27-30: one pseudo-inverse step per block, then bounds enforced by
        clamping),
        'newton' (that step iterated to convergence per block, then bounds enforced by clamping).
    window, overlap : blocks per OSQP window and blocks of look-ahead solved with it but committed
        by the next window (qp only). Memory stays flat for any program length.
    step_tol_um : re-linearise until the largest change of a correction is below this (um or urad).
    max_iterations : Newton / SQP iterations at most.
    subdivide_tol_um : insert internal nodes in a feed move when the corrected path, interpolated
        linearly between the corrected end points, would miss the midpoint by more than this (um,
        and urad times orientation_weight); None or 0: end points only.
    max_subdivision_depth : recursion depth of that test (2**depth pieces per move at most).
    ramp_nodes : give a straight feed move after a block left uncorrected the internal nodes the
        step bound needs to ramp its correction in along it (:mod:`._ramp`; default True, also
        with ``subdivide_tol_um`` None); False for a program whose writer cannot write them.
    always_qp : solve every window with OSQP even when the unbounded solution satisfies every bound
        (the result is the same; for tests and timing).
    osqp_eps : absolute and relative tolerance of OSQP (solutions are polished on the active set).
    progress : callable(blocks_done: int) called every few seconds, or None (called from the
        planning thread when there is more than one).
    extrapolate : correct blocks outside the region the model's data reached (its support) too;
        default False: they get no correction (their bounds are zero; the step bound ramps the
        corrections of their neighbours in and out).
    max_correction_sd_um : a block whose correction's standard error (the model's covariance, um)
        exceeds this gets no correction, like one outside the support, and neither does the rest
        of its contour (a run of feed moves cut one after the other: :mod:`._contours`); rapids
        keep their own rule. None or 0: no such limit. Models without a covariance are not
        limited.
    threads : threads for the per-block work and for planning ahead of the consumer of
        ``Planner.iter_chunks``; 0 (default): ``$MTCOMP_THREADS`` if set, else the CPUs available,
        at most 4; 1: everything in the calling thread. The plan is the same for any number.
    """

    method: str = "qp"
    window: int = 4096
    overlap: int = 256
    step_tol_um: float = 0.01
    max_iterations: int = 20
    subdivide_tol_um: float | None = 0.5
    max_subdivision_depth: int = 6
    ramp_nodes: bool = True
    always_qp: bool = False
    osqp_eps: float = 1e-7
    progress: object = field(default=None, compare=False)
    threads: int = 0
    extrapolate: bool = False
    max_correction_sd_um: float | None = DEFAULT_MAX_CORRECTION_SD_UM

    def __post_init__(self):
        if self.method not in METHODS:
            raise InputError(f"unknown method {self.method!r} (choose {', '.join(METHODS)})")
        if self.window < 1 or self.overlap < 0:
            raise ValueError("window must be >= 1 and overlap >= 0")
        if self.threads < 0:
            raise ValueError("threads must be >= 0")
