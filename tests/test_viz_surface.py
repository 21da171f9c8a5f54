"""The surface a program cuts and the deviation along its normal (mtcomp.viz.surface), against
hand-derived cases and the numpy reference model."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp import InputError, load_machine
from mtcomp.models import ErrorModel, FittedModel
from mtcomp.models.reference import reference_deviation
from mtcomp.viz.surface import (pair_compensated, program_error_map, read_program_points,
                                select_surface_points, triangulate_xy, vertex_normals)

A, B = 0.10, -0.05  # tilted plane z = A x + B y - 5 (mm)


def plane_program(path, shift_x=0.0, extra_points=False, n=9):
    """A zig-zag raster of the plane z = A x + B y - 5 over 40 x 40 mm, G0 retracts between rows."""
    lines = ["%", "G21 G90 G17", "G0 Z20", "F500"]
    xs = np.linspace(-20.0, 20.0, n)
    for i, y in enumerate(np.linspace(-20.0, 20.0, n)):
        row = xs if i % 2 == 0 else xs[::-1]
        lines.append(f"G0 X{row[0] + shift_x:.4f} Y{y:.4f}")
        prev = None
        for x in row:
            z = A * x + B * y - 5.0
            if extra_points and prev is not None:  # an intermediate point, as a planner may add
                xm = 0.5 * (prev + x)
                lines.append(f"G1 X{xm + shift_x:.4f} Y{y:.4f} Z{A * xm + B * y - 5.0:.4f}")
            lines.append(f"G1 X{x + shift_x:.4f} Y{y:.4f} Z{z:.4f}")
            prev = x
        lines.append("G0 Z20")
    lines += ["M30", "%"]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_select_surface_points_keeps_the_lowest_point_per_xy():
    tips = np.array([[0, 0, 5.0], [1, 0, 0.0], [0, 0, -1.0], [0, 0.0004, -2.0], [2, 0, 3.0]])
    # (0, 0.0004) rounds to the same 1 um cell as (0, 0): the lowest of the three is index 3
    np.testing.assert_array_equal(select_surface_points(tips), [1, 3, 4])


def test_triangulation_does_not_bridge_the_hole_of_a_ring():
    t = np.linspace(0, 2 * np.pi, 73)[:-1]
    rings = [np.column_stack([r * np.cos(t), r * np.sin(t), np.zeros_like(t)]) for r in (19, 20, 21)]
    pts = np.vstack(rings)
    tri = triangulate_xy(pts)
    centroids = pts[tri].mean(axis=1)
    assert np.all(np.linalg.norm(centroids[:, :2], axis=1) > 18.5)
    # and the ring itself is covered: the triangles' area is the polygonal annulus between r 19 and
    # 21 plus at most the slivers of three consecutive points of the inner ring (< 2 %)
    a, b, c = (pts[tri[:, i]] for i in range(3))
    area = 0.5 * np.abs(np.cross(b - a, c - a)[:, 2]).sum()
    annulus = 36 * np.sin(2 * np.pi / 72) * (21 ** 2 - 19 ** 2)
    assert annulus <= area + 1e-9 and area < 1.02 * annulus


def test_vertex_normals_of_a_plane_are_its_normal_turned_to_the_tool():
    x, y = np.meshgrid(np.linspace(0, 10, 6), np.linspace(0, 10, 6))
    pts = np.column_stack([x.ravel(), y.ravel(), (A * x + B * y).ravel()])
    tri = triangulate_xy(pts)
    up = np.tile([0.0, 0.0, 1.0], (pts.shape[0], 1))
    expected = np.array([-A, -B, 1.0]) / np.sqrt(A ** 2 + B ** 2 + 1)
    np.testing.assert_allclose(vertex_normals(pts, tri, up), np.tile(expected, (36, 1)),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(vertex_normals(pts, tri, -up), -np.tile(expected, (36, 1)),
                               rtol=0, atol=1e-12)


@pytest.fixture()
def xfyz_model():
    machine = load_machine("xfyz")
    fitted = FittedModel.zero(ErrorModel(machine))
    for name, value in {"EXX_1": 30.0, "EZX_2": -40.0, "EYY_1": 12.0, "C0Y": -57.78, "A0Z": -29.28,
                        "B0Z": 48.99, "EBX_1": 80.0, "EAY_1": -60.0}.items():
        fitted.params.set_file_value(name, value)
    return machine, fitted


def test_map_of_a_plane_matches_the_reference_model(tmp_path, xfyz_model):
    machine, fitted = xfyz_model
    prog = plane_program(tmp_path / "plane.nc")
    smap = program_error_map(machine, fitted, prog)
    assert smap.points.shape == (81, 3)  # the 9 x 9 cutting points; retracts and rapids left out
    n = np.array([-A, -B, 1.0]) / np.sqrt(A ** 2 + B ** 2 + 1)
    np.testing.assert_allclose(smap.normals, np.tile(n, (81, 1)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(smap.points[:, 2], A * smap.points[:, 0] + B * smap.points[:, 1] - 5,
                               rtol=0, atol=1e-9)
    params = dict(zip(fitted.model.param_names, fitted.params.values))
    ctx = {"feed": 500.0, "tool_length": machine.tool_length}
    ref = np.array([reference_deviation(machine, params, q, ctx)[:3] for q in smap.tips])
    np.testing.assert_allclose(smap.dev_before, ref, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(smap.dn_before_um, 1e3 * ref @ n, rtol=1e-9, atol=1e-9)
    assert np.max(np.abs(smap.dn_before_um)) > 0.1  # the case is not trivially zero
    st = smap.stats()
    assert st["rms_before_um"] == pytest.approx(np.sqrt(np.mean((1e3 * ref @ n) ** 2)), rel=1e-9)
    assert "rms_after_um" not in st


def test_compensated_map_compares_with_the_original_nominal_points(tmp_path):
    """Error-free model, 'compensated' program shifted by +10 um in X: after = 10 um * n_x exactly."""
    machine = load_machine("xfyz")
    fitted = FittedModel.zero(ErrorModel(machine))
    prog = plane_program(tmp_path / "plane.nc")
    comp = plane_program(tmp_path / "plane_c.nc", shift_x=0.010)
    smap = program_error_map(machine, fitted, prog, comp)
    n = np.array([-A, -B, 1.0]) / np.sqrt(A ** 2 + B ** 2 + 1)
    np.testing.assert_allclose(smap.dn_before_um, 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(smap.dev_after, np.tile([0.010, 0, 0], (81, 1)), rtol=0, atol=1e-9)
    np.testing.assert_allclose(smap.dn_after_um, 10.0 * n[0], rtol=0, atol=1e-6)


def test_compensated_program_with_extra_points_is_paired_in_order(tmp_path):
    machine = load_machine("xfyz")
    orig = read_program_points(plane_program(tmp_path / "a.nc"), machine)
    comp = read_program_points(plane_program(tmp_path / "b.nc", shift_x=0.004, extra_points=True),
                               machine)
    assert len(comp) > len(orig)
    idx = pair_compensated(orig, comp, machine)
    cut = ~orig.rapid[1:]  # the first move (G0 Z20 from home) is the same in both programs
    np.testing.assert_allclose(comp.q[idx[1:]][cut] - orig.q[1:][cut],
                               np.tile([0.004, 0, 0], (int(cut.sum()), 1)), rtol=0, atol=1e-9)
    assert np.all(np.diff(idx) >= 1)


def test_a_program_that_is_not_the_compensated_one_is_refused(tmp_path, xfyz_model):
    machine, fitted = xfyz_model
    prog = plane_program(tmp_path / "a.nc")
    other = plane_program(tmp_path / "b.nc", shift_x=1.5)  # 1.5 mm: far beyond any correction
    with pytest.raises(InputError, match=r"b\.nc.*not a compensated version"):
        program_error_map(machine, fitted, prog, other)


def test_programs_without_a_surface_are_refused(tmp_path, xfyz_model):
    machine, fitted = xfyz_model
    rapid = tmp_path / "rapid.nc"
    rapid.write_text("G0 X1 Y2 Z3\nG0 X4\n")
    with pytest.raises(InputError, match="no feed moves"):
        program_error_map(machine, fitted, rapid)
    line = tmp_path / "line.nc"
    line.write_text("G1 X0 Y0 Z0 F100\nG1 X10 Y10\nG1 X20 Y20\nG1 X30 Y30\n")
    with pytest.raises(InputError, match="on a line"):
        program_error_map(machine, fitted, line)


def test_tool_radius_moves_the_drawing_to_the_contact_points(tmp_path, xfyz_model):
    machine, fitted = xfyz_model
    prog = plane_program(tmp_path / "plane.nc")
    flat = program_error_map(machine, fitted, prog)
    ball = program_error_map(machine, fitted, prog, tool_radius_mm=3.0)
    n = np.array([-A, -B, 1.0]) / np.sqrt(A ** 2 + B ** 2 + 1)
    # contact point = ball centre (tip + R z) minus R n
    np.testing.assert_allclose(ball.points, flat.tips + 3.0 * (np.array([0, 0, 1.0]) - n),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(ball.dn_before_um, flat.dn_before_um, rtol=0, atol=1e-12)
