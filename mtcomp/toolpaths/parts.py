"""Test programs: the bowl of Qi and Yang (2016), ISO 230-4 ballbar circles, the three-sphere set-ups
of Tan et al. (2026) and a 5-axis cone frustum (NAS 979 / ISO 10791-7 style). Each writer returns the
nominal geometry (docs/references.md lists the papers).

Conventions: G-code positions are tool-tip positions (docs/toolpaths.md). Lengths mm, angles rad in
Python; the programs carry mm and deg (4 decimals). Every program is written with atomic_write.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_write
from ..kinematics import forward
from ..machine import Machine
from .inverse import fit_rotary_travel, inverse_kinematics

# ----------------------------------------------------------------------------------- helpers


def _words(machine: Machine, q: np.ndarray, letters: str | None = None) -> str:
    """'X.. Y.. Z.. A.. C..' for one pose q (n_axes,) mm and rad (4 decimals, deg for rotary)."""
    out = []
    for name, v in zip(machine.axis_names, q):
        if letters is not None and name not in letters:
            continue
        val = math.degrees(v) if name in "ABC" else v
        s = f"{val:.4f}"
        out.append(f"{name}{'0.0000' if s == '-0.0000' else s}")
    return " ".join(out)


def _write_lines(path, lines: list[str]) -> None:
    with atomic_write(path) as f:
        f.write("\n".join(lines) + "\n")


def _check_travel(machine: Machine, q: np.ndarray, what: str) -> None:
    lo, hi = machine.travel_bounds()
    bad = (q < lo - 1e-9) | (q > hi + 1e-9)
    if np.any(bad):
        i, j = np.argwhere(bad)[0]
        name = machine.axis_names[j]
        v = math.degrees(q[i, j]) if name in "ABC" else q[i, j]
        raise InputError(f"{what}: axis {name} would need {v:.4f}, outside the travel of machine "
                         f"{machine.name}; move the part (origin) or choose a smaller one")


def save_table(path, table: dict[str, np.ndarray]) -> None:
    """Write a table of columns (equal-length arrays) as CSV (docs/measurements.md), atomically."""
    cols = list(table)
    n = len(next(iter(table.values())))
    with atomic_write(path, newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for i in range(n):
            w.writerow([(f"{table[c][i]:.6f}" if isinstance(table[c][i], (float, np.floating))
                         else table[c][i]) for c in cols])


# ------------------------------------------------------------------ bowl of Qi and Yang (2016)
BOWL_SIDE_MM = 80.0
BOWL_DEPTH_MM = 13.8


def bowl_surface(x, y, side: float = BOWL_SIDE_MM, depth: float = BOWL_DEPTH_MM):
    """Height z (mm) of the bowl at (x, y) mm, part frame (centre at the origin, rim at z = 0).

    z = -depth (1 - u^2)^2 (1 - v^2)^2 with u = 2x/side, v = 2y/side inside the square, 0 outside:
    13.8 mm deep at the centre, 0 with zero slope along the edges of the 80 x 80 mm square (Qi and
    Yang (2016), section 4, model the part as a NURBS bowl of these dimensions; this bi-quartic has
    the same size and is smooth, so tests can check against it).
    """
    u = np.clip(2.0 * np.asarray(x, float) / side, -1.0, 1.0)
    v = np.clip(2.0 * np.asarray(y, float) / side, -1.0, 1.0)
    return -depth * (1 - u * u) ** 2 * (1 - v * v) ** 2


def bowl_normal(x, y, side: float = BOWL_SIDE_MM, depth: float = BOWL_DEPTH_MM) -> np.ndarray:
    """Unit normals (..., 3) of the bowl at (x, y), pointing up out of the material."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    u = np.clip(2.0 * x / side, -1.0, 1.0)
    v = np.clip(2.0 * y / side, -1.0, 1.0)
    fu = -depth * 2 * (1 - u * u) * (-2 * u) * (1 - v * v) ** 2
    fv = -depth * (1 - u * u) ** 2 * 2 * (1 - v * v) * (-2 * v)
    fx, fy = fu * 2.0 / side, fv * 2.0 / side
    n = np.stack([-fx, -fy, np.ones_like(fx)], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


@dataclass
class BowlToolpath:
    """The bowl finishing path: N points, workpiece frame, mm.

    tool_tips : (N, 3) programmed positions (the ball's lowest point on the vertical tool axis).
    ball_centres : (N, 3). contact_points : (N, 3) on the surface. normals : (N, 3) unit, upwards.
    origin : (3,) where the part centre (rim level) sits. ball_radius : mm.
    """

    path: str
    tool_tips: np.ndarray
    ball_centres: np.ndarray
    contact_points: np.ndarray
    normals: np.ndarray
    origin: np.ndarray
    ball_radius: float
    side: float = BOWL_SIDE_MM
    depth: float = BOWL_DEPTH_MM


def write_bowl_program(path, ball_radius_mm: float = 3.0, stepover_mm: float = 0.5,
                       step_mm: float = 0.5, feed_mm_min: float = 1200.0,
                       origin_mm=(0.0, 0.0, 0.0), safe_z_mm: float = 10.0,
                       side_mm: float = BOWL_SIDE_MM, depth_mm: float = BOWL_DEPTH_MM) -> BowlToolpath:
    """Write the bowl finishing program of Qi and Yang (2016) (zig-zag raster along X, ball-end of
    radius 3 mm).

    Qi and Yang (2016), section 4, cut the bowl with a ball-end tool "of radius 3 mm" (半径为 3 mm),
    the default.

    Contact points lie on a regular (x, y) grid (``step_mm`` along a pass, ``stepover_mm`` between
    passes); the ball centre is the contact point plus ``ball_radius`` along the surface normal,
    the programmed tool tip is the centre minus ``ball_radius`` along Z. The part centre at rim level
    sits at ``origin_mm`` in the workpiece frame (default: the machine origin, well inside the XFYZ
    travel). Blocks after the first cut are modal continuation lines ``X.. Y.. Z..``.
    """
    for name, v in (("ball_radius_mm", ball_radius_mm), ("stepover_mm", stepover_mm),
                    ("step_mm", step_mm), ("feed_mm_min", feed_mm_min), ("side_mm", side_mm)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise InputError(f"{name} must be a positive number, got {v!r}")
    half = 0.5 * side_mm
    ny = int(round(side_mm / stepover_mm))
    nx = int(round(side_mm / step_mm))
    ys = np.linspace(-half, half, ny + 1)
    xs = np.linspace(-half, half, nx + 1)
    X = np.tile(xs, (ny + 1, 1))
    X[1::2] = X[1::2, ::-1]                      # zig-zag
    Y = np.repeat(ys[:, None], nx + 1, axis=1)
    cx, cy = X.ravel(), Y.ravel()
    contact = np.stack([cx, cy, bowl_surface(cx, cy, side_mm, depth_mm)], axis=1)
    normals = bowl_normal(cx, cy, side_mm, depth_mm)
    centres = contact + ball_radius_mm * normals
    origin = np.asarray(origin_mm, float).reshape(3)
    tips = centres - np.array([0.0, 0.0, ball_radius_mm]) + origin
    centres = centres + origin
    contact = contact + origin
    lines = ["%", "O0001 (QI-YANG 2016 BOWL 80 X 80 X 13.8, BALL R%.3f)" % ball_radius_mm,
             "G21 G90 G17", "T1 M6 (BALL END)", "S12000 M3",
             f"G0 Z{origin[2] + safe_z_mm:.4f}",
             f"G0 X{tips[0, 0]:.4f} Y{tips[0, 1]:.4f}",
             f"G1 Z{tips[0, 2]:.4f} F{feed_mm_min / 2:g}",
             f"G1 X{tips[0, 0]:.4f} Y{tips[0, 1]:.4f} Z{tips[0, 2]:.4f} F{feed_mm_min:g}"]
    lines += [f"X{p[0]:.4f} Y{p[1]:.4f} Z{p[2]:.4f}" for p in tips[1:]]
    lines += [f"G0 Z{origin[2] + safe_z_mm:.4f}", "M5", "M30", "%"]
    _write_lines(path, lines)
    return BowlToolpath(str(path), tips, centres, contact, normals, origin, float(ball_radius_mm),
                        side_mm, depth_mm)


# ------------------------------------------------------------------------ ISO 230-4 ballbar circle
_PLANES = {"XY": (17, 0, 1, 2), "ZX": (18, 2, 0, 1), "YZ": (19, 1, 2, 0)}


@dataclass
class CircleTest:
    """An ISO 230-4 circular test: the program and the nominal data-capture points.

    table : columns of a ballbar file (docs/measurements.md) for ``n_points`` points of the 360 deg
        data arc: x_mm, y_mm, z_mm (+ a_deg/b_deg/c_deg at 0), table_ball_*, tool_ball_* (0: the tool ball
        centre is the programmed tip), length_mm (= radius), feed_mm_min, angle_deg.
    """

    path: str
    radius: float
    centre: np.ndarray
    plane: str
    direction: str
    table: dict = field(default_factory=dict)


def write_circle_program(path, machine: Machine, radius_mm: float = 100.0,
                         centre_mm=(0.0, 0.0, 0.0), plane: str = "XY", direction: str = "ccw",
                         feed_mm_min: float = 1000.0, overshoot_deg: float = 90.0,
                         start_deg: float = 0.0, feed_in_mm: float = 1.5,
                         n_points: int = 360) -> CircleTest:
    """Write a ballbar circle (ISO 230-4): radial feed-in, lead-in arc of ``overshoot_deg``, the full
    360 deg data arc, overshoot arc of ``overshoot_deg``, radial feed-out.

    plane : 'XY' (G17), 'ZX' (G18) or 'YZ' (G19); angles are measured in the plane's (first, second)
    axes, so that 'ccw' (G3) is counter-clockwise seen from the positive end of the normal axis.
    """
    plane = plane.upper()
    if plane not in _PLANES:
        raise InputError(f"plane must be XY, ZX or YZ, got {plane!r}")
    direction = direction.lower()
    if direction not in ("cw", "ccw"):
        raise InputError(f"direction must be cw or ccw, got {direction!r}")
    if not radius_mm > feed_in_mm >= 0:
        raise InputError("radius_mm must exceed feed_in_mm >= 0")
    g, i0, i1, _ = _PLANES[plane]
    s = 1.0 if direction == "ccw" else -1.0
    code = "G3" if s > 0 else "G2"
    c = np.asarray(centre_mm, float).reshape(3)

    def point(angle_deg, r):
        p = c.copy()
        a = math.radians(angle_deg)
        p[i0] += r * math.cos(a)
        p[i1] += r * math.sin(a)
        return p

    def xyz(p):
        return f"X{p[0]:.4f} Y{p[1]:.4f} Z{p[2]:.4f}"

    def arc_to(angle_deg, start_angle_deg):
        p = point(angle_deg, radius_mm)
        off = c - point(start_angle_deg, radius_mm)
        letters = {0: "I", 1: "J", 2: "K"}
        return f"{code} {xyz(p)} {letters[i0]}{off[i0]:.4f} {letters[i1]}{off[i1]:.4f}"

    a_in = start_deg - s * overshoot_deg
    a_out = start_deg + s * overshoot_deg
    lines = ["%", f"O0230 (ISO 230-4 CIRCLE R{radius_mm:g} {plane} {direction.upper()} F{feed_mm_min:g})",
             f"G21 G90 G{g}", f"G0 {xyz(point(a_in, radius_mm - feed_in_mm))}",
             f"G1 {xyz(point(a_in, radius_mm))} F{feed_mm_min:g} (FEED IN)"]
    if overshoot_deg > 0:
        lines.append(arc_to(start_deg, a_in) + " (LEAD-IN ARC)")
    lines.append(arc_to(start_deg, start_deg) + " (DATA ARC 360 DEG)")
    if overshoot_deg > 0:
        lines.append(arc_to(a_out, start_deg) + " (OVERSHOOT ARC)")
    lines += [f"G1 {xyz(point(a_out, radius_mm - feed_in_mm))} (FEED OUT)", "M30", "%"]
    _write_lines(path, lines)
    ang = start_deg + s * 360.0 * np.arange(n_points) / n_points
    pts = np.array([point(a, radius_mm) for a in ang])
    table = {"x_mm": pts[:, 0], "y_mm": pts[:, 1], "z_mm": pts[:, 2]}
    for ax in machine.rotary_axes:
        table[f"{ax.name.lower()}_deg"] = np.zeros(n_points)
    table.update({
        "table_ball_x_mm": np.full(n_points, c[0]), "table_ball_y_mm": np.full(n_points, c[1]),
        "table_ball_z_mm": np.full(n_points, c[2]),
        "tool_ball_x_mm": np.zeros(n_points), "tool_ball_y_mm": np.zeros(n_points),
        "tool_ball_z_mm": np.zeros(n_points), "length_mm": np.full(n_points, float(radius_mm)),
        "feed_mm_min": np.full(n_points, float(feed_mm_min)), "angle_deg": ang})
    return CircleTest(str(path), float(radius_mm), c, plane, direction, table)


# ------------------------------------------------------ three-sphere set-ups of Tan et al. (2026)
@dataclass
class ThreeSphereTest:
    """Tan et al. (2026), section 2.1: ballbar along X, Y, Z at two heights, only C moving.

    table : ballbar columns (docs/measurements.md) per reading: axis positions (x_mm ... c_deg), table
    ball at (C axis, height) in the workpiece frame, tool ball 0 (the programmed tip), length_mm = bar,
    plus ``setup`` ('X', 'Y' or 'Z'), ``height_mm`` and ``block_line`` (line of the C move).
    """

    path: str
    table: dict


def write_three_sphere_program(path, machine: Machine, heights_mm=(100.0, 200.0),
                               bar_mm: float = 100.0, step_deg: float = 10.0,
                               c_range_deg=(0.0, 360.0), feed_deg_min: float = 1800.0,
                               dwell_s: float = 1.0) -> ThreeSphereTest:
    """Write the three-sphere measurement of the C axis (the set-up of Tan et al. (2026), eqs. 10-14).

    The table ball sits on the nominal C axis line at ``height`` above the table face (z = 0 of the
    workpiece frame); the tool ball at table ball + bar * (X, Y or Z direction) with every rotary
    axis at zero, then only C steps by ``step_deg`` through ``c_range_deg`` with a dwell per
    reading. ``M0`` stops ask the operator to mount and remove the bar. The F of the C moves is
    deg/min (as most controls read F for a rotary-only block).
    """
    if "C" not in machine.axis_names or machine.axis("C").side != "workpiece":
        raise InputError(f"machine {machine.name} has no C table: the three-sphere test needs one")
    if not step_deg > 0:
        raise InputError(f"step_deg must be positive, got {step_deg!r}")
    ci = machine.index("C")
    px, py, _ = machine.axis("C").axis_point
    lo, hi = c_range_deg
    angles = np.arange(lo, hi + 1e-9, step_deg)
    lines = ["%", f"O0003 (TAN ET AL. 2026 THREE-SPHERE, BAR {bar_mm:g} MM, STEP {step_deg:g} DEG)",
             "G21 G90 G17"]
    rows = []
    for h in heights_mm:
        ball = np.array([px, py, float(h)])
        for setup, d in (("X", [1, 0, 0]), ("Y", [0, 1, 0]), ("Z", [0, 0, 1])):
            tool = ball + bar_mm * np.asarray(d, float)
            q0 = np.zeros(machine.n_axes)
            q0[[machine.index(c) for c in "XYZ"]] = tool   # rotary at 0: workpiece = machine frame
            q0[ci] = math.radians(angles[0])
            lines.append(f"G0 {_words(machine, q0)}")
            lines.append(f"M0 (MOUNT BALLBAR ALONG {setup}, TABLE BALL AT H={h:g})")
            for a in angles:
                q = q0.copy()
                q[ci] = math.radians(a)
                lines.append(f"G1 C{a:.4f} F{feed_deg_min:g}")
                rows.append((q, ball, setup, float(h), len(lines)))
                # the program is a Fanuc-style one ('%', O number): G04's P is milliseconds, a
                # whole number (FANUC 0i-F operator's manual, "Dwell (G04)"; Haas reads a P
                # without a decimal point as milliseconds too): P1 was 1 ms, not 1 s
                lines.append(f"G4 P{round(dwell_s * 1000.0):d}")
            lines.append("M0 (REMOVE BALLBAR)")
    lines += ["M30", "%"]
    q = np.array([r[0] for r in rows])
    _check_travel(machine, q, "three-sphere test")
    _write_lines(path, lines)
    table = {}
    for j, name in enumerate(machine.axis_names):
        table[f"{name.lower()}_{'deg' if name in 'ABC' else 'mm'}"] = (
            np.degrees(q[:, j]) if name in "ABC" else q[:, j])
    balls = np.array([r[1] for r in rows])
    table.update({"table_ball_x_mm": balls[:, 0], "table_ball_y_mm": balls[:, 1],
                  "table_ball_z_mm": balls[:, 2], "tool_ball_x_mm": np.zeros(len(rows)),
                  "tool_ball_y_mm": np.zeros(len(rows)), "tool_ball_z_mm": np.zeros(len(rows)),
                  "length_mm": np.full(len(rows), float(bar_mm)),
                  "setup": np.array([r[2] for r in rows]),
                  "height_mm": np.array([r[3] for r in rows]),
                  "block_line": np.array([r[4] for r in rows])})
    return ThreeSphereTest(str(path), table)


# ------------------------------------------------------------------------ 5-axis cone frustum
@dataclass
class ConeFrustum:
    """The cone frustum finishing pass (flank milling), nominal geometry.

    Part: base diameter, top diameter, height (mm), half_angle (rad); its axis is tilted by
    ``tilt`` (rad) about Y and its base centre sits at ``base_centre`` (workpiece frame).
    part2wp : (4, 4) the part frame (z along the cone axis, base at z = 0) in the workpiece frame.
    q : (N, n_axes) axis positions of the contour poses (mm, rad), in program order.
    tips : (N, 3) tool tips (centre of the end face) and tool_axes (N, 3), workpiece frame.
    contact_base : (N, 3) lower end of the contact line on the base circle; normals (N, 3) outward
        cone normals there. lines : (N,) program line of each contour block. tool_radius : mm.
    """

    path: str
    base_diameter: float
    top_diameter: float
    height: float
    half_angle: float
    tilt: float
    base_centre: np.ndarray
    part2wp: np.ndarray
    tool_radius: float
    q: np.ndarray
    tips: np.ndarray
    tool_axes: np.ndarray
    contact_base: np.ndarray
    normals: np.ndarray
    lines: np.ndarray

    @property
    def slant_height(self) -> float:
        return self.height / math.cos(self.half_angle)


def write_cone_frustum_program(path, machine: Machine, base_diameter_mm: float = 80.0,
                               top_diameter_mm: float = 56.0, half_angle_deg: float = 15.0,
                               tilt_deg: float = 10.0, base_centre_mm=(0.0, 0.0, 20.0),
                               tool_radius_mm: float = 5.0, n_points: int = 360,
                               feed_mm_min: float = 1000.0, branch: int = 1,
                               clearance_mm: float = 10.0) -> ConeFrustum:
    """Write a 5-axis flank-milling pass around a cone frustum (NAS 979 / ISO 10791-7 style).

    The cone has half-angle 15 deg and, like the NAS 979 part, its axis is inclined (``tilt_deg``,
    about Y) so that all five axes move. The side of a cylindrical end mill of radius
    ``tool_radius_mm`` touches the cone along a whole generator line: the tool axis is parallel to
    the generator (pointing away from the base) and offset by the tool radius along the outward
    normal; the tool tip (centre of the end face) sits at base level. The height follows from the
    two diameters and the half-angle. Axis positions come from :func:`inverse_kinematics` (branch
    and rotary wrap as documented there, then made continuous over the pass by
    :func:`fit_rotary_travel`); the pass makes one full turn, approached and left along the outward
    normal by ``clearance_mm``.
    """
    alpha = math.radians(half_angle_deg)
    if not 0 < alpha < math.pi / 2:
        raise InputError("half_angle_deg must be between 0 and 90")
    if not base_diameter_mm > top_diameter_mm > 0:
        raise InputError("base_diameter_mm must exceed top_diameter_mm > 0")
    if n_points < 3:
        raise InputError("n_points must be >= 3")
    rb = 0.5 * base_diameter_mm
    height = 0.5 * (base_diameter_mm - top_diameter_mm) / math.tan(alpha)
    tilt = math.radians(tilt_deg)
    ct, st = math.cos(tilt), math.sin(tilt)
    R = np.array([[ct, 0, st], [0, 1, 0], [-st, 0, ct]])
    base_centre = np.asarray(base_centre_mm, float).reshape(3)
    part2wp = np.eye(4)
    part2wp[:3, :3] = R
    part2wp[:3, 3] = base_centre
    phi = 2 * math.pi * np.arange(n_points + 1) / n_points
    cphi, sphi = np.cos(phi), np.sin(phi)
    ca, sa = math.cos(alpha), math.sin(alpha)
    normal_l = np.stack([ca * cphi, ca * sphi, np.full_like(phi, sa)], 1)
    gen_l = np.stack([-sa * cphi, -sa * sphi, np.full_like(phi, ca)], 1)
    base_l = np.stack([rb * cphi, rb * sphi, np.zeros_like(phi)], 1)
    tips_l = base_l + tool_radius_mm * normal_l
    to_wp = lambda v: v @ R.T                                   # noqa: E731 (directions)
    tips = to_wp(tips_l) + base_centre
    axes = to_wp(gen_l)
    normals = to_wp(normal_l)
    contact = to_wp(base_l) + base_centre
    approach = tips[0] + clearance_mm * normals[0]
    leave = tips[-1] + clearance_mm * normals[-1]
    all_tips = np.vstack([approach, tips, leave])
    all_axes = np.vstack([axes[0], axes, axes[-1]])
    q_all = fit_rotary_travel(machine, inverse_kinematics(machine, all_tips, all_axes, branch=branch))
    _check_travel(machine, q_all, "cone frustum")
    q = q_all[1:-1]
    lines = ["%", f"O0979 (CONE FRUSTUM D{base_diameter_mm:g}/D{top_diameter_mm:g} "
             f"HALF-ANGLE {half_angle_deg:g} TILT {tilt_deg:g}, END MILL R{tool_radius_mm:g})",
             "G21 G90 G17", "T2 M6 (END MILL)", "S8000 M3",
             f"G0 {_words(machine, q_all[0])}"]
    first = len(lines) + 1
    lines.append(f"G1 {_words(machine, q[0])} F{feed_mm_min:g}")
    lines += [_words(machine, qi) for qi in q[1:]]
    lines += [f"G1 {_words(machine, q_all[-1])}", "M5", "M30", "%"]
    _write_lines(path, lines)
    return ConeFrustum(str(path), float(base_diameter_mm), float(top_diameter_mm), height, alpha,
                       tilt, base_centre, part2wp, float(tool_radius_mm), q, tips, axes, contact,
                       normals, np.arange(first, first + len(q)))


def tool_poses(machine: Machine, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nominal tool tips (N, 3) and tool axes (N, 3) of axis positions q (N, n_axes):
    :func:`mtcomp.kinematics.forward`."""
    return forward(machine, q)
