"""truth: an independent virtual CNC machine for tests and benchmarks of mtcomp.

Nothing here imports mtcomp: the simulator is written from the ISO 230-1 definitions with its own
4x4 homogeneous transforms (:mod:`truth.transforms`), numpy and scipy. It reads the machine TOML
files (``mtcomp/machines/*.toml``) with :mod:`tomllib` for topology, travel, ``axis_point_mm`` and
``tool_length_mm``, and writes measurement files in the SPEC section 3 formats with :mod:`csv`.
Tests import it as ``from truth import TruthMachine, campaigns`` (pytest puts ``tests/`` on sys.path).

Usage
-----
::

    rng = np.random.default_rng(7)
    m = TruthMachine.random("CAFXYZ", rng, effects=[Backlash("X", 6.0)])
    tip, axis = m.true_pose(q, tool_length=100.0, context=Context(feed_mm_min=2000, dirs={"X": -1}))
    d_tip, d_axis = m.true_deviation(q)                # actual - nominal, workpiece frame, mm
    res = campaigns.points(m, tmp_path / "points.csv", rng)       # SPEC 3.1 file, res.ideal, res.setup
    res = campaigns.laser(m, tmp_path / "laser_x.csv", rng, "X", optic_mm=(0, 150, 80))
    files = campaigns.full_campaign(m, tmp_path, rng)   # points, laser per axis, ballbar, three-sphere

Units and frames
----------------
Inside: mm and **rad**. ``q`` (N, n_axes) lists the axes present in the order X Y Z A B C (linear in mm,
rotary in rad); errors are mm and rad; outputs are mm (tip, deviations) and unit vectors (tool axis).
Files: mm, deg, um, urad, mm/min, s, degC (the writers convert). Frames follow docs/conventions.md:
``bed`` (machine), ``wp`` (the table; coincides with bed when every axis is at 0), carriage frame of
each axis (coincides with bed at 0), ``tool`` (origin at the tip, +Z from the tip towards the spindle).
Transforms ``A2B`` map coordinates in A to B; composition reads right to left.

Nominal kinematics: the topology string lists before ``F`` the axes from the workpiece towards the bed
and after ``F`` those from the bed towards the tool. A tool-side linear axis translates its carriage by
``+s`` along its axis; a table linear axis translates the table by ``-s``; a rotary axis turns the table
by ``+theta`` right-handed about +X/+Y/+Z (A/B/C) through its ``axis_point_mm``. ``wp2bed = W_1 ... W_m``
(bed towards workpiece), ``tool2bed = A_1 ... A_n S`` (bed towards tool, S the spindle),
``tool2wp = wp2bed^-1 tool2bed``. Tool length compensation: q is the commanded tip. With every axis
at 0 the tip of the reference tool (``reference_tool_mm`` = L0, the machine file's ``tool_length_mm``)
is at the origin, where every frame coincides, and the spindle gauge point L0 above it along +Z. A tool
of length L puts the ram (Z, when it is the last tool-side axis) at its machine position
``z + L - L0`` (its translation and its error profiles are those of that position) and hangs L below
the gauge point, so the tip is at the commanded point. So on a 3-axis machine q is the tip position in
the workpiece frame, and on XFYZ/CAFXYZ/CBFXYZ the X, Y, Z positions are the tip in the bed frame.

What is modelled, where each error acts, and the signs
-------------------------------------------------------
*Linear axis* ``a`` at position ``s`` (six component errors, profiles of s: ``components[a]``):
``delta = (EX a, EY a, EZ a)`` (mm) and the angles ``EA a, EB a, EC a`` (rad), rotation
``R = Rx(EA) Ry(EB) Rz(EC)``.

* tool side: carriage in its parent = ``Trans(s u) Trans(delta) Trans(p) R Trans(-p)``: the carriage
  translates by delta and turns by R about the pivot p, a point fixed in the carriage frame
  (``pivots[a]``, random: within +-150 mm in X and Y and 50-400 mm above the spindle gauge point at
  q = 0, i.e. somewhere on the slide; for the spindle carriage 20-300 mm above the gauge point).
  Everything it carries (the following axes, the spindle, the tool) turns with it. The tool-side
  carriage frames have their origin at the reference tool's tip at q = 0, so a pivot fixed on the
  slide is given relative to the gauge point there: p + (0, 0, L0) in carriage coordinates, whatever
  the tool. The Abbe arm of the tip is (tip position in that carriage frame) - p - (0, 0, L0): on
  XFYZ for Y ``(0, 0, z - L0) - p_Y``, the same for every tool at the same tip (a longer tool raises
  the ram, not the tip); for the ram Z ``-(p_Z + (0, 0, L))``: the tip hangs L below the gauge point.
* table side: table in the bed = ``Trans(-s u) Trans(p) R^T Trans(-p) Trans(-delta)``, so the tool
  relative to the table moves by ``Trans(delta) Trans(p) R Trans(-p) Trans(s u)``: the component
  errors of a table axis are the error motion of the tool relative to the table (what a laser reads,
  so ``EXX`` is the positioning error on either side), and the angles act about the pivot p fixed in
  the table's frame (travelling with the table; random on the table: |x| <= 250, |y| <= 150,
  z in [-120, -20] mm). The arm of the tip is ``(x, y, z) - p`` (table coordinates of the tip), not
  ``(0, y, z)``: a table's yaw therefore also adds a position-dependent straightness.
* ``u`` is the actual direction of travel (squareness, X the reference): ``u_X = e_x``,
  ``u_Y = Rz(C0Y) e_y`` (Y leans towards -X for C0Y > 0: ``dx = -y sin C0Y``),
  ``u_Z = Ry(B0Z) Rx(A0Z) e_z`` (``dx = +z sin B0Z cos A0Z``, ``dy = -z sin A0Z``).
* Profiles (random machines): cubic splines through random values at random knots plus sums of
  sines (no polynomials), held constant outside the travel; positioning optionally shaped on the real
  ISO 230-2 run ``/work/shared/data/real/iso230_2/ess_b02_<axis>.csv`` (mean per target, stretched
  over the travel, 85 % of the shape). Positioning 5-30 um peak-to-peak plus a constant within +-5 um,
  straightness 2-10 um p-p plus +-3 um, angular 5-30 urad p-p **with a constant part: 3-20 urad in
  magnitude at s = 0** (never anchored at zero); translational errors need not vanish at 0 either.

*Spindle*: the tool frame in the last tool-side carriage (the ram's) =
``Trans(g) Ry(tb) Rx(ta) Trans(-g) Trans(0, 0, L0 - L)``, ``g = (0, 0, L0)`` the spindle gauge point, ``(ta, tb) = spindle_tilt`` (rad, 3-30 urad each): the tool
axis is ``Ry(tb) Rx(ta) e_z`` and the tip moves by ``L (-cos ta sin tb, sin ta, 1 - cos ta cos tb)``,
so tool lengths (``tool_mm``) reveal the tilt.

*Rotary axis* (workpiece side only) at ``theta``: table in its parent =
``Trans(m) [Trans(c) R_tilt Trans(-c)] [Trans(c) Rot(u, theta + E_pos(theta)) Trans(-c)]``:

* location errors (``location``): the actual line passes through ``c = axis_point + offsets`` with
  direction u. C: offsets (X0C, Y0C, 0) mm, ``u = Ry(B0C) Rx(A0C) e_z``; A: (0, Y0A, Z0A),
  ``u = Rz(C0A) Ry(B0A) e_x``; B: (X0B, 0, Z0B), ``u = Rz(C0B) Rx(A0B) e_y``. They act only through
  the rotation (no effect at theta = 0). Random: offsets 5-40 um, tilts 10-60 urad.
* angular positioning ``E_pos`` (ECC, EAA, EBB): the table turns by ``theta + E_pos`` (ISO: actual
  minus commanded angle); random: a constant 5-30 urad plus harmonics 1..5 of 3-15 urad (decaying).
* error motions, in the parent frame and not turning with the table: translation
  ``m = (EX., EY., EZ.)`` (radial pair + axial), then the two tilts about the actual axis point c
  (C: ``Rx(EAC) Ry(EBC)``; A: ``Ry(EBA) Rz(ECA)``; B: ``Rx(EAB) Rz(ECB)``). Random (``error_motions``):
  harmonics 2..5, 1-4 um and 2-8 urad. Once-per-revolution run-out is the hidden effect
  ``RotaryRunout``.

*Hidden effects* (:mod:`truth.effects`, off unless passed in ``effects``): ``Backlash`` (linear,
``EXX += dir * B/2``), ``RotaryBacklash``, ``PeriodicError``, ``FeedOffset`` (um per m/min, uniform,
optionally signed by dir), ``FeedAbbe`` (seed 000: angle gain per m/min and/or a pivot (IRC) shift in
mm per m/min), ``ThermalDrift`` (drivers ``time`` settling exponential, ``linear``, ``temperature``
channel, ``spindle`` first-order lag over a ``SpindleSchedule``; a translation of the spindle along the
machine axes), ``RotaryRunout`` (eccentricity, wobble, axial run-out), ``LocalDefect`` (raised-cosine
bump). ``random_effect(kind, machine, rng)`` draws one with realistic parameters (kinds named as in
SPEC 6).

Context (:class:`Context`): ``feed_mm_min`` (default 0), ``dirs`` {axis: +1/-1} (default +1),
``t_s`` (0), ``temperatures`` {name: degC}, ``spindle_rpm``.

Measurements (conventions where SPEC 3 leaves a choice)
--------------------------------------------------------
* points: ``dx, dy, dz`` = R_s p_actual + t_s - p_nominal (workpiece frame, um), the tracker set-up
  (R_s a small rotation about the workpiece origin, t_s a translation) drawn per file.
* laser: the measured point is the tip plus ``optic_*_mm``, a vector fixed to the tool and given in the
  workpiece frame at the nominal pose (the same convention for ``tool_ball_*_mm``). Translational
  E<d>.: d-component of (actual - nominal position of that point). Angular E<d>.: the rotation vector
  of ``R R0^T`` (tool relative to workpiece, actual against nominal), its d-component. In a run of a
  rotary axis carrying the workpiece both kinds are negated (the table relative to the tool:
  ECC = actual - commanded angle, EXC the table's radial motion).
  Directions are those of the workpiece frame (linear runs are made with rotary axes at 0, where it
  coincides with the bed frame). Set-up per (axis, component): zero offset; straightness of linear
  axes also a slope (um/m) times the target. This agrees with docs/measurements.md and mtcomp's
  reading of these files as documented there.
* ballbar: ``length_mm`` = |actual tool-ball centre - table-ball centre| + the file's calibration
  offset + noise; the table ball is fixed in the workpiece frame.
* thermal: ``disp_<c>_um`` = component c of the tip deviation, zeroed at the first reading (ISO 230-3).
* velocity (seed 000): minus the velocity of the table points M, N in the bed frame (the motion in
  the sense of the axis, so V0 = dir * feed as docs/measurements.md uses it), M and N in table
  coordinates; the rotation centre is the table's pivot shifted by the straightness slope and by
  ``FeedAbbe``'s IRC shift.
* Every writer: ``setup=False`` and zero noise give the machine's readings exactly; a machine with a
  ``ThermalDrift`` records ``spindle_rpm`` and ``temp_<name>_c`` (a ``ThermalEnvironment``) in every
  file, and the writers take ``t0_s`` so that a campaign runs on one clock.

:func:`form_error` (Kabsch) gives the form error of cut points; ``TruthMachine.cut`` the actual tip of
commanded (e.g. compensated) axis positions.
"""
from .effects import (EFFECT_KINDS, Backlash, FeedAbbe, FeedOffset, LocalDefect, PeriodicError,
                      RotaryBacklash, RotaryRunout, SpindleSchedule, ThermalDrift, ThermalEnvironment,
                      random_effect)
from .machine import Context, FormError, TruthMachine, form_error, read_machine_file
from . import campaigns, profiles, transforms

__all__ = ["TruthMachine", "Context", "form_error", "FormError", "read_machine_file", "campaigns",
           "profiles", "transforms", "Backlash", "RotaryBacklash", "PeriodicError", "FeedOffset",
           "FeedAbbe", "ThermalDrift", "SpindleSchedule", "ThermalEnvironment", "RotaryRunout",
           "LocalDefect", "random_effect", "EFFECT_KINDS"]
