"""A B/C trunnion campaign (CBFXYZ) from a plain numpy truth that shares no code with mtcomp: ISO
230-2 positioning runs of X, Y and Z (0.3 um noise), two R-test balls read at B x C with B approached
from both sides (0.5 um noise, and a B backlash no base model has: 1.2 to 1.8 um of misfit), and a
ball-bar circle in XY (0.3 um). The files' noise differs by a factor of five, so per-file weights
matter. Truth: squareness, both rotary axes' location errors, curved positioning and straightness
of the linear axes, B's positioning, C's wobble."""
from __future__ import annotations

import numpy as np

from truth import transforms as T
from truth.campaigns import write_csv

UM, URAD = 1e-3, 1e-6
B_POINT, C_POINT = np.array([0.0, 0.0, -60.0]), np.zeros(3)
TRUTH_URAD = {"C0Y": 20.0, "B0Z": -15.0, "A0Z": 10.0}
LOCATION = dict(X0B=12.0, Z0B=-8.0, A0B=20.0, C0B=30.0, X0C=15.0, Y0C=-10.0, A0C=25.0, B0C=-20.0)
MACHINE_TOML = """name = "umc750"
topology = "CBFXYZ"
tool_length_mm = 100.0
[axes.X]
travel_mm = [-380.0, 380.0]
[axes.Y]
travel_mm = [-254.0, 254.0]
[axes.Z]
travel_mm = [-300.0, 200.0]
[axes.B]
travel_deg = [-35.0, 110.0]
axis_point_mm = [0.0, 0.0, -60.0]
[axes.C]
travel_deg = [-360.0, 360.0]
axis_point_mm = [0.0, 0.0, 0.0]
"""


def _exx(x):
    u = x / 380.0
    return (12.0 * u + 4.0 * (1 - 3 * u ** 2) + 1.5 * np.sin(np.pi * u * 3)) * UM


def _eyy(y):
    u = y / 254.0
    return (-8.0 * u + 3.0 * (1 - 3 * u ** 2)) * UM


def _ezz(z):
    u = (z + 50) / 250.0
    return (6.0 * u - 2.0 * (1 - 3 * u ** 2)) * UM


def _rx(a):
    return T.rot_x(a)[0, :3, :3]


def _ry(a):
    return T.rot_y(a)[0, :3, :3]


def _rz(a):
    return T.rot_z(a)[0, :3, :3]


def _about(axis, point, angle):
    """4x4: rotation by ``angle`` about the line through ``point`` along ``axis`` (Rodrigues)."""
    axis = axis / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = R, point - R @ point
    return M


def _wp2bed(b, c, err=True, dir_b=0.0):
    if not err:
        return _about(np.array([0, 1.0, 0]), B_POINT, b) @ _about(np.array([0, 0, 1.0]), C_POINT, c)
    L = LOCATION
    bp = B_POINT + np.array([L["X0B"], 0, L["Z0B"]]) * UM
    bd = _rz(L["C0B"] * URAD) @ _rx(L["A0B"] * URAD) @ np.array([0, 1.0, 0])
    b_actual = b + 15.0 * URAD * np.sin(b) - 15.0 * URAD * dir_b          # EBB, a 30 urad backlash
    cp = C_POINT + np.array([L["X0C"], L["Y0C"], 0]) * UM
    cd = _ry(L["B0C"] * URAD) @ _rx(L["A0C"] * URAD) @ np.array([0, 0, 1.0])
    wobble = _about(np.array([1.0, 0, 0]), cp, 8.0 * URAD * np.cos(c))
    return _about(bd, bp, b_actual) @ wobble @ _about(cd, cp, c)


def _tip_bed(x, y, z):
    u = x / 380.0
    p = np.array([x + _exx(x), 3.0 * (1 - 3 * u ** 2) * UM, -2.0 * (1 - 3 * u ** 2) * UM])
    s = TRUTH_URAD
    uy = _rz(s["C0Y"] * URAD) @ np.array([0, 1.0, 0])
    uz = _ry(s["B0Z"] * URAD) @ _rx(s["A0Z"] * URAD) @ np.array([0, 0, 1.0])
    return p + (y + _eyy(y)) * uy + (z + _ezz(z)) * uz


def _tip_wp(x, y, z, b, c, dir_b=0.0):
    return (np.linalg.inv(_wp2bed(b, c, True, dir_b)) @ np.append(_tip_bed(x, y, z), 1.0))[:3]


def _write(path, header, rows):
    return write_csv(path, dict(zip(header, zip(*rows))))


def _laser(folder, rng, axis, targets, static, zero_um):
    rows = []
    for run in range(1, 6):
        for d in (1, -1):
            for t in (targets if d == 1 else targets[::-1]):
                q = dict(static)
                q[axis.lower()] = t
                dev = _tip_bed(q["x"], q["y"], q["z"])["XYZ".index(axis)] - t
                rows.append([axis, f"E{axis}{axis}", f"{t:.3f}", d, run,
                             f"{dev / UM + zero_um + rng.normal(0, 0.3):.2f}", *static.values()])
    return _write(folder / f"laser_{axis.lower()}.csv",
                  ["axis", "component", "target_mm", "dir", "run", "value_um", "x_mm", "y_mm", "z_mm"], rows)


def _rtest(folder, rng, name, ball, placed_um):
    rows, actual = [], ball + np.asarray(placed_um) * UM
    for run, dir_b in ((1, 1), (2, -1)):
        for b_deg in (-30, 0, 30, 60, 90)[::dir_b]:
            for c_deg in range(0, 360, 45):
                b, c = np.radians(b_deg), np.radians(c_deg)
                q = (_wp2bed(b, c, False) @ np.append(ball, 1.0))[:3]
                dev = (_tip_wp(*q, b, c, dir_b) - actual) / UM + rng.normal(0, 0.5, 3)
                rows.append([*(f"{v:.4f}" for v in q), b_deg, c_deg, *(f"{v:.2f}" for v in dev), dir_b, run])
    return _write(folder / name, ["x_mm", "y_mm", "z_mm", "b_deg", "c_deg", "dx_um", "dy_um", "dz_um",
                                  "dir_b", "run"], rows)


def _ballbar(folder, rng):
    rows, radius, zc = [], 150.0, -100.0
    centre = np.array([3.0, -2.0, 1.0]) * UM + np.array([0.0, 0.0, zc])
    for run, sense in ((1, 1), (2, -1)):
        for k in range(360):
            th = np.radians(k) * sense
            x, y = radius * np.cos(th), radius * np.sin(th)
            length = np.linalg.norm(_tip_wp(x, y, zc, 0.0, 0.0) - centre) + rng.normal(0, 0.3) * UM
            rows.append([f"{x:.4f}", f"{y:.4f}", f"{zc:.3f}", 0, 0, zc, 0, 0, 0, f"{length:.6f}", 1000,
                         1 if -np.sin(th) * sense >= 0 else -1, 1 if np.cos(th) * sense >= 0 else -1, run])
    return _write(folder / "ballbar_xy.csv", ["x_mm", "y_mm", "z_mm", "table_ball_x_mm", "table_ball_y_mm",
                                              "table_ball_z_mm", "tool_ball_x_mm", "tool_ball_y_mm",
                                              "tool_ball_z_mm", "length_mm", "feed_mm_min", "dir_x", "dir_y",
                                              "run"], rows)


def trunnion_campaign(folder, seed: int = 42):
    """(machine file, [laser_x, laser_y, laser_z, rtest 1, rtest 2, ball bar]) written in ``folder``."""
    rng = np.random.default_rng(seed)
    (folder / "umc750.toml").write_text(MACHINE_TOML)
    paths = [_laser(folder, rng, "X", np.linspace(-360, 360, 13), dict(x=0, y=0, z=-100), 2.0),
             _laser(folder, rng, "Y", np.linspace(-240, 240, 9), dict(x=0, y=0, z=-100), -1.0),
             _laser(folder, rng, "Z", np.linspace(-300, 200, 11), dict(x=0, y=0, z=0), 0.5),
             _rtest(folder, rng, "rtest_ball1.csv", np.array([100.0, 0.0, 50.0]), [20, -15, 5]),
             _rtest(folder, rng, "rtest_ball2.csv", np.array([-50.0, 80.0, 120.0]), [-10, 25, -8]),
             _ballbar(folder, rng)]
    return folder / "umc750.toml", paths
