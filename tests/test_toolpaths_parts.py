"""Test-part programs against their analytic geometry, read back through the G-code reader."""
import math

import numpy as np
import pytest
from scipy.optimize import minimize

from mtcomp import InputError, load_machine
from mtcomp.kinematics import forward
from mtcomp.toolpaths import read_program
from mtcomp.toolpaths.parts import (bowl_normal, bowl_surface, save_table, write_bowl_program,
                                    write_circle_program, write_cone_frustum_program,
                                    write_three_sphere_program)

XFYZ = load_machine("xfyz")


def test_bowl_surface_dimensions():
    assert bowl_surface(0.0, 0.0) == pytest.approx(-13.8, rel=0, abs=1e-15)
    edge = np.linspace(-40, 40, 17)
    np.testing.assert_allclose(bowl_surface(edge, 40.0), 0.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(bowl_surface(-40.0, edge), 0.0, rtol=0, atol=1e-15)
    # normals against finite-difference tangents of the surface equation
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-39, 39, (2, 50))
    h = 1e-6
    tx = np.stack([np.full(50, 2 * h), np.zeros(50), bowl_surface(x + h, y) - bowl_surface(x - h, y)], 1)
    ty = np.stack([np.zeros(50), np.full(50, 2 * h), bowl_surface(x, y + h) - bowl_surface(x, y - h)], 1)
    n = bowl_normal(x, y)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(np.einsum("ij,ij->i", n, tx) / (2 * h), 0, rtol=0, atol=1e-7)
    np.testing.assert_allclose(np.einsum("ij,ij->i", n, ty) / (2 * h), 0, rtol=0, atol=1e-7)
    assert np.all(n[:, 2] > 0)


def test_bowl_program_touches_the_surface(tmp_path):
    r = 1.5
    origin = np.array([10.0, -20.0, -50.0])
    bowl = write_bowl_program(tmp_path / "bowl.nc", ball_radius_mm=r, stepover_mm=2.0, step_mm=1.0,
                              origin_mm=origin)
    prog = read_program(tmp_path / "bowl.nc", XFYZ)
    cuts = np.array([b.end for b in prog.blocks if b.motion == 1])
    # the first G1 is the plunge onto the first point; then one block per contact point
    tips = cuts[1:]
    assert len(tips) == len(bowl.tool_tips) == 41 * 81
    np.testing.assert_allclose(tips, bowl.tool_tips, rtol=0, atol=5.01e-5)
    # deepest tip: the ball touches the bottom of the bowl at the centre
    assert tips[:, 2].min() == pytest.approx(origin[2] - 13.8, rel=0, abs=5.01e-5)
    # every ball centre is at one ball radius from the surface, nearest point found by minimisation
    rng = np.random.default_rng(3)
    for i in rng.choice(len(tips), 60, replace=False):
        c = tips[i] + [0, 0, r] - origin

        def d2(p):
            return (p[0] - c[0]) ** 2 + (p[1] - c[1]) ** 2 + (bowl_surface(p[0], p[1]) - c[2]) ** 2
        best = min((minimize(d2, x0, method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-16})
                    for x0 in (c[:2], bowl.contact_points[i, :2] - origin[:2])), key=lambda s: s.fun)
        assert math.sqrt(best.fun) == pytest.approx(r, rel=0, abs=1e-4)
    # no gouge anywhere near: dense surface samples around a few centres stay >= r away
    gx, gy = np.meshgrid(np.linspace(-3, 3, 121), np.linspace(-3, 3, 121))
    for i in rng.choice(len(tips), 20, replace=False):
        c = tips[i] + [0, 0, r] - origin
        sx, sy = c[0] + gx, c[1] + gy
        dist = np.sqrt((sx - c[0]) ** 2 + (sy - c[1]) ** 2 + (bowl_surface(sx, sy) - c[2]) ** 2)
        assert dist.min() >= r - 1e-4


@pytest.mark.parametrize("plane, direction, normal", [
    ("XY", "ccw", [0, 0, 1]), ("XY", "cw", [0, 0, 1]), ("ZX", "ccw", [0, 1, 0]), ("YZ", "cw", [1, 0, 0]),
])
def test_circle_program(tmp_path, plane, direction, normal):
    centre = np.array([5.0, -10.0, 20.0])
    t = write_circle_program(tmp_path / "c.nc", XFYZ, radius_mm=100.0, centre_mm=centre, plane=plane,
                             direction=direction, overshoot_deg=45.0, n_points=36)
    prog = read_program(tmp_path / "c.nc", XFYZ, chord_tol_mm=1e-3)
    arcs = [b for b in prog.blocks if b.motion in (2, 3)]
    assert [b.motion for b in arcs] == [3 if direction == "ccw" else 2] * 3
    normal = np.array(normal, float)
    total = 0.0
    for b in arcs:
        pts = np.vstack([b.start, b.points]) - centre
        np.testing.assert_allclose(pts @ normal, 0.0, rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(pts, axis=1), 100.0, rtol=0, atol=2e-4)
        turn = np.arctan2(np.cross(pts[:-1], pts[1:]) @ normal, np.einsum("ij,ij->i", pts[:-1], pts[1:]))
        assert np.all(np.sign(turn) == (1 if direction == "ccw" else -1))
        total += abs(turn.sum())
    assert math.degrees(total) == pytest.approx(45 + 360 + 45, rel=0, abs=1e-6)
    # the nominal table: points on the circle, ballbar length = |tool ball - table ball| by FK
    tab = t.table
    q = np.stack([tab["x_mm"], tab["y_mm"], tab["z_mm"]], 1)
    tip, _ = forward(XFYZ, q)
    ball = np.stack([tab["table_ball_x_mm"], tab["table_ball_y_mm"], tab["table_ball_z_mm"]], 1)
    np.testing.assert_allclose(np.linalg.norm(tip - ball, axis=1), tab["length_mm"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(tab["length_mm"], 100.0, rtol=0, atol=0)
    save_table(tmp_path / "c.csv", tab)
    head = (tmp_path / "c.csv").read_text().splitlines()[0].split(",")
    assert head[:3] == ["x_mm", "y_mm", "z_mm"] and "length_mm" in head


@pytest.mark.parametrize("name", ["cafxyz", "cbfxyz"])
def test_three_sphere_program(tmp_path, name):
    m = load_machine(name)
    t = write_three_sphere_program(tmp_path / "s.nc", m, step_deg=30.0)
    tab = t.table
    assert len(tab["c_deg"]) == 2 * 3 * 13
    prog = read_program(tmp_path / "s.nc", m)
    by_line = {b.line: b for b in prog.blocks}
    moving = set()
    for i, line in enumerate(tab["block_line"]):
        b = by_line[int(line)]
        moved = np.flatnonzero(np.abs(b.end - b.start) > 0)
        moving.update(m.axis_names[j] for j in moved)
        np.testing.assert_allclose(np.degrees(b.end[m.index("C")]), tab["c_deg"][i], rtol=0, atol=1e-9)
    assert moving == {"C"}              # only C moves during the readings
    q = np.stack([tab[f"{c.lower()}_{'deg' if c in 'ABC' else 'mm'}"] for c in m.axis_names], 1)
    q[:, 3:] = np.radians(q[:, 3:])
    tip, _ = forward(m, q)
    ball = np.stack([tab["table_ball_x_mm"], tab["table_ball_y_mm"], tab["table_ball_z_mm"]], 1)
    np.testing.assert_allclose(np.linalg.norm(tip - ball, axis=1), 100.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sorted(set(tab["height_mm"])), [100.0, 200.0], rtol=0, atol=0)
    with pytest.raises(InputError, match="no C table"):
        write_three_sphere_program(tmp_path / "x.nc", XFYZ)


def test_three_sphere_dwell_is_in_milliseconds_as_a_fanuc_reads_it(tmp_path):
    """The program is Fanuc-style ('%', O0003): a Fanuc reads G04's P as whole milliseconds (a Haas
    a P without a decimal point too), so a dwell of 1.5 s is P1500 (it was written P1.5: 1.5 ms)
    after every reading's C move."""
    write_three_sphere_program(tmp_path / "s.nc", load_machine("cafxyz"), step_deg=90.0, dwell_s=1.5)
    lines = (tmp_path / "s.nc").read_text().splitlines()
    dwells = [ln for ln in lines if ln.startswith("G4")]
    moves = [i for i, ln in enumerate(lines) if ln.startswith("G1 C")]
    assert dwells and set(dwells) == {"G4 P1500"}
    assert all(lines[i + 1] == "G4 P1500" for i in moves)


@pytest.mark.parametrize("name", ["cafxyz", "cbfxyz"])
def test_cone_frustum_program(tmp_path, name):
    m = load_machine(name)
    cone = write_cone_frustum_program(tmp_path / "cone.nc", m, n_points=120)
    assert cone.top_diameter == pytest.approx(80 - 2 * cone.height * math.tan(math.radians(15)),
                                              rel=1e-12, abs=0)
    assert cone.height == pytest.approx(12 / math.tan(math.radians(15)), rel=1e-12, abs=0)
    prog = read_program(tmp_path / "cone.nc", m)
    by_line = {b.line: b for b in prog.blocks}
    q = np.array([by_line[int(k)].end for k in cone.lines])
    written = np.array([5.01e-5] * 3 + [math.radians(5.01e-5)] * 2)   # 4 decimals, mm and deg
    assert np.all(np.abs(q - cone.q) <= written)
    # the program's poses by forward kinematics, in the part frame (z along the cone axis)
    tip, k = forward(m, q)
    wp2part = np.linalg.inv(cone.part2wp)
    tip_p = tip @ wp2part[:3, :3].T + wp2part[:3, 3]
    k_p = k @ wp2part[:3, :3].T
    alpha = cone.half_angle
    # tool axis parallel to a generator: at the half-angle from the cone axis, in the tip's meridian
    np.testing.assert_allclose(k_p[:, 2], math.cos(alpha), rtol=0, atol=2e-6)
    # along the whole contact length, the tool axis runs one tool radius off the cone surface
    for t in np.linspace(0, cone.slant_height, 5):
        p = tip_p + t * k_p
        rho = np.hypot(p[:, 0], p[:, 1])
        dist = (rho - (0.5 * cone.base_diameter - p[:, 2] * math.tan(alpha))) * math.cos(alpha)
        np.testing.assert_allclose(dist, cone.tool_radius, rtol=0, atol=5e-4)
    # the contact line covers the frustum: from the base circle to the top circle, all around
    low = tip_p - cone.tool_radius * np.stack([np.cos(alpha) * tip_p[:, 0] / np.hypot(tip_p[:, 0], tip_p[:, 1]),
                                               np.cos(alpha) * tip_p[:, 1] / np.hypot(tip_p[:, 0], tip_p[:, 1]),
                                               np.full(len(tip_p), np.sin(alpha))], 1)
    np.testing.assert_allclose(np.hypot(low[:, 0], low[:, 1]), 40.0, rtol=0, atol=5e-4)
    top = low + cone.slant_height * k_p
    np.testing.assert_allclose(np.hypot(top[:, 0], top[:, 1]), 28.0, rtol=0, atol=5e-4)
    np.testing.assert_allclose(top[:, 2], cone.height, rtol=0, atol=5e-4)
    ang = np.unwrap(np.arctan2(tip_p[:, 1], tip_p[:, 0]))
    assert abs(ang[-1] - ang[0]) == pytest.approx(2 * math.pi, rel=0, abs=1e-6)
    # the rotary axes move continuously (no wrap jumps) and the tilt keeps its branch
    assert np.all(np.abs(np.diff(q[:, 3:], axis=0)) < math.radians(10))
    assert np.all(q[:, 3] > 0)
