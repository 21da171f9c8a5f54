"""The surface a program cuts and the deviation along its normal (mtcomp.viz.surface), against
hand-derived cases and the numpy reference model."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp import InputError, load_machine
from mtcomp.models import ErrorModel, FittedModel
from reference_model import reference_deviation, reference_tool_pose
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
    machine = load_machine("xfyz").with_basis("polynomial")
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
    machine = load_machine("xfyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine))
    prog = plane_program(tmp_path / "plane.nc")
    comp = plane_program(tmp_path / "plane_c.nc", shift_x=0.010)
    smap = program_error_map(machine, fitted, prog, comp)
    n = np.array([-A, -B, 1.0]) / np.sqrt(A ** 2 + B ** 2 + 1)
    np.testing.assert_allclose(smap.dn_before_um, 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(smap.dev_after, np.tile([0.010, 0, 0], (81, 1)), rtol=0, atol=1e-9)
    np.testing.assert_allclose(smap.dn_after_um, 10.0 * n[0], rtol=0, atol=1e-6)


def test_compensated_program_with_extra_points_is_paired_in_order(tmp_path):
    machine = load_machine("xfyz").with_basis("polynomial")
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


def test_programs_without_a_surface_are_mapped_as_their_path(tmp_path, xfyz_model):
    """No surface seen along Z (only rapids, a straight line, a lathe profile): the points of the
    path, with the deviation along the tool axis (+Z on this machine), and no triangles."""
    from mtcomp.viz.surface import predicted_points
    machine, fitted = xfyz_model
    rapid = tmp_path / "rapid.nc"
    rapid.write_text("G0 X1 Y2 Z3\nG0 X4\n")
    m = program_error_map(machine, fitted, rapid)
    assert m.triangles.shape == (0, 3)
    np.testing.assert_allclose(m.tips, [[1, 2, 3], [4, 2, 3]], rtol=0, atol=1e-12)
    line = tmp_path / "line.nc"
    line.write_text("G1 X0 Y0 Z0 F100\nG1 X10 Y10\nG1 X20 Y20\nG1 X30 Y30\n")
    m = program_error_map(machine, fitted, line)
    assert m.triangles.shape == (0, 3) and m.points.shape == (4, 3)
    np.testing.assert_allclose(m.normals, np.tile([0, 0, 1.0], (4, 1)), rtol=0, atol=1e-12)
    q = np.array([[0, 0, 0], [10, 10, 0], [20, 20, 0], [30, 30, 0.0]])
    dz = predicted_points(fitted, q, np.full(4, 100.0), np.ones((4, 3)))[:, 2] - q[:, 2]
    np.testing.assert_allclose(m.dn_before_um, dz * 1e3, rtol=0, atol=1e-9)


def test_ball_end_maps_the_ball_centre_deviation_at_the_contact_points(tmp_path, xfyz_model):
    """Ball end of radius R: drawn at the contact points tip + R (z - n); mapped deviation is that of
    the ball centre, tip + R * (actual tool axis), from the numpy reference."""
    machine, fitted = xfyz_model
    prog = plane_program(tmp_path / "plane.nc")
    flat = program_error_map(machine, fitted, prog)
    ball = program_error_map(machine, fitted, prog, tool_radius_mm=3.0)
    n = np.array([-A, -B, 1.0]) / np.sqrt(A ** 2 + B ** 2 + 1)
    np.testing.assert_allclose(ball.points, flat.tips + 3.0 * (np.array([0, 0, 1.0]) - n),
                               rtol=0, atol=1e-12)
    params = dict(zip(fitted.model.param_names, fitted.params.values))
    ctx = {"feed": 500.0, "tool_length": machine.tool_length}
    ref = []
    for q in ball.tips:
        tip, axis = reference_tool_pose(machine, params, q, ctx)
        ref.append(tip + 3.0 * axis - (q + [0, 0, 3.0]))
    np.testing.assert_allclose(ball.dev_before, np.array(ref), rtol=1e-7, atol=1e-10)
    # the tool's tilt moves the ball centre by up to R * angle: visible, but small against the tip's
    diff = np.abs(ball.dn_before_um - flat.dn_before_um)
    assert 1e-4 < diff.max() < 0.3 * np.abs(flat.dn_before_um).max()


def test_cutting_runs_split_at_links_and_corners():
    from mtcomp.viz.surface import cutting_runs
    square = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [3, 1, 0], [3, 2, 0], [3, 3, 0],
              [13, 3, 0], [14, 3, 0], [15, 3, 0], [16, 3, 0], [16, 3, 9]]
    runs = cutting_runs(np.array(square, float))
    # a corner at (3, 0) shared by both sides; the 10 mm link starts a new run; the last step turns up
    assert [r.tolist() for r in runs] == [[0, 1, 2, 3], [3, 4, 5, 6], [7, 8, 9, 10]]


def test_built_in_parts_are_recognised_by_their_header(tmp_path):
    from mtcomp.toolpaths.parts import write_bowl_program, write_cone_frustum_program
    from mtcomp.viz.surface import program_hints
    write_bowl_program(tmp_path / "b.nc", ball_radius_mm=2.5, stepover_mm=10.0, step_mm=10.0)
    assert program_hints(tmp_path / "b.nc") == {"tool_radius_mm": 2.5, "part": "bowl of Qi and Yang (2016)"}
    write_cone_frustum_program(tmp_path / "c.nc", load_machine("cafxyz"), n_points=24)
    h = program_hints(tmp_path / "c.nc")
    assert h["tool_radius_mm"] == 5.0
    # slant height of the default frustum: (80 - 56) / 2 / sin(15 deg)
    assert h["flank_length_mm"] == pytest.approx(12.0 / np.sin(np.radians(15.0)), rel=1e-12)
    assert program_hints(plane_program(tmp_path / "p.nc")) == {}


def test_bowl_contact_points_match_the_generator(tmp_path):
    """The contact points reconstructed from the tool tips (triangulated normals) against the bowl
    generator's analytic contact points and normals."""
    from mtcomp.toolpaths.parts import write_bowl_program
    machine = load_machine("xfyz").with_basis("polynomial")
    tp = write_bowl_program(tmp_path / "bowl.nc", ball_radius_mm=3.0, stepover_mm=2.0, step_mm=2.0,
                            origin_mm=(100.0, 50.0, -20.0))
    smap = program_error_map(machine, FittedModel.zero(ErrorModel(machine)), tmp_path / "bowl.nc")
    from scipy.spatial import cKDTree
    dist, k = cKDTree(tp.tool_tips).query(smap.tips)
    assert dist.max() < 1e-4                          # the program's 4 decimals
    inner = np.all(np.abs(tp.contact_points[k, :2] - [100.0, 50.0]) < 36.0, axis=1)  # off the rim
    # normals of the triangulated 2 mm raster: a discretisation, good to about 1 % here
    np.testing.assert_allclose(smap.normals[inner], tp.normals[k][inner], rtol=0, atol=0.015)
    np.testing.assert_allclose(smap.points[inner], tp.contact_points[k][inner], rtol=0, atol=0.05)
    rms = np.sqrt(np.mean(np.sum((smap.points[inner] - tp.contact_points[k][inner]) ** 2, axis=1)))
    assert rms < 0.01


def test_flank_map_of_the_cone_frustum(tmp_path):
    """5-axis flank milling: contact lines along the tool axis, normals from the path and the axis,
    against the generator's cone geometry; the error-free model maps zero, a pure tip offset maps
    its normal component."""
    from mtcomp.toolpaths.parts import write_cone_frustum_program
    machine = load_machine("cafxyz").with_basis("polynomial")
    cone = write_cone_frustum_program(tmp_path / "cone.nc", machine, n_points=72)
    fitted = FittedModel.zero(ErrorModel(machine))
    smap = program_error_map(machine, fitted, tmp_path / "cone.nc")   # header: flank, R5
    levels = smap.points.shape[0] // len(cone.q)
    assert smap.points.shape[0] == levels * len(cone.q) and levels >= 2
    base = smap.points[::levels]                      # height 0: the base circle
    np.testing.assert_allclose(base, cone.contact_base, rtol=0, atol=1e-3)
    np.testing.assert_allclose(smap.normals[::levels], cone.normals, rtol=0, atol=2e-3)
    top = smap.points[levels - 1::levels]             # the top circle, radius 28 in the part frame
    local = (top - cone.base_centre) @ cone.part2wp[:3, :3]
    np.testing.assert_allclose(np.hypot(local[:, 0], local[:, 1]), 28.0, rtol=0, atol=2e-3)
    np.testing.assert_allclose(local[:, 2], cone.height, rtol=0, atol=2e-3)
    np.testing.assert_allclose(smap.dn_before_um, 0.0, rtol=0, atol=1e-9)
    # a random machine: dn of each contact point is n . (deviation of the tool point at h a), which
    # the cmm measurement model computes with its own CasADi function (a second formulation)
    from mtcomp.measurement.readings_extra import normal_deviation
    from mtcomp.sim import random_truth
    from mtcomp.viz.surface import read_program_points
    truth = random_truth(machine, np.random.default_rng(5))
    smap = program_error_map(machine, truth, tmp_path / "cone.nc")
    prog = read_program_points(tmp_path / "cone.nc", machine)
    cut = np.flatnonzero(~prog.rapid)[:len(cone.q)]
    q = np.repeat(prog.q[cut], levels, axis=0)
    c = truth.context(len(q), {"feed": np.full(len(q), 1000.0)})
    ref = 1e3 * normal_deviation(truth.model, q, truth.params.values, c, smap.offsets, smap.normals)
    # referenced to the part's datum, the program's origin (the tip's deviation there, approach
    # directions unknown and feed 0: the model's default context)
    from mtcomp.models import deviation
    datum = deviation(truth.model, np.zeros((1, machine.n_axes)), truth.params.values,
                      truth.model.default_context(1))[0, :3]
    ref = ref - 1e3 * smap.normals @ datum
    np.testing.assert_allclose(smap.dn_before_um, ref, rtol=1e-8, atol=1e-9)
    assert np.abs(ref).max() > 1.0
    h = np.linalg.norm(smap.offsets, axis=1)
    assert h.max() == pytest.approx(12.0 / np.sin(np.radians(15.0)), rel=1e-9)


def test_compensated_program_paired_through_its_lines_and_the_report(tmp_path, capsys):
    """A program that revisits the same points (where pairing by proximity fails): the compensated
    blocks are found through the kept lines, or through the report's source lines."""
    from mtcomp.cli import main
    from mtcomp.models import ErrorModel, FittedModel, save_model
    from mtcomp.viz.surface import pair_compensated, read_program_points, report_points
    from mtcomp import load_machine
    machine = load_machine("xfyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine))
    rng = np.random.default_rng(4)
    fitted.params.values[:] = rng.normal(size=len(fitted.params.values)) * np.array(
        [1e-3 if s.unit == "um" else 1e-5 for s in fitted.params.specs])     # 1 um, 10 urad
    model = tmp_path / "m.json"
    save_model(model, fitted)
    passes = "".join(f"(pass {k})\nG0 X0 Y{k}\nG1 Z-1 F500\nG2 X0 Y{k} I5 J0\nG1 X20\nX0\nG0 Z5\n"
                     for k in range(3))
    prog = tmp_path / "in.nc"
    prog.write_text("G21 G90\nG0 Z5\n" + passes + passes + "M30\n")
    out, rep = tmp_path / "out.nc", tmp_path / "b.csv"
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--report",
                 str(rep), "--quiet"]) == 0
    orig = read_program_points(prog, machine)
    comp = read_program_points(out, machine)
    idx = pair_compensated(orig, comp, machine)
    # every original end is paired with a compensated end of the same pass: the comment line before
    # it in the output is the one before it in the source
    src_lines = prog.read_text().splitlines()
    out_lines = out.read_text().splitlines()

    def pass_of(lines, n):
        return next(lines[k] for k in range(n - 1, -1, -1) if lines[k].startswith("(pass"))
    for i in range(len(orig)):
        if orig.line[i] > 2:
            assert pass_of(src_lines, orig.line[i]) == pass_of(out_lines, comp.line[idx[i]])
    assert np.all(np.diff(idx) >= 0)
    rp = report_points(orig, rep, machine)
    np.testing.assert_array_equal(rp.line, orig.line)
    np.testing.assert_allclose(rp.q, orig.q, rtol=0, atol=0.05)
    capsys.readouterr()
    assert main(["render", "xfyz", str(model), str(prog), "--report", str(rep), "-o",
                 str(tmp_path / "map.png"), "--backend", "matplotlib", "--size", "300x150"]) == 0
    assert "model prediction after" in capsys.readouterr().out


def test_predicted_points_and_export_errors_use_the_held_position():
    """A model whose data held Z at -50 mm: render's predicted points and export's model errors at
    any Z carry the deviation the model has at Z = -50 (the numpy oracle's, at the same X, Y),
    as compensate's corrections do, not the model's own extrapolation along Z."""
    from mtcomp.export._tables import model_errors
    from mtcomp.viz.surface import predicted_points
    machine = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(machine)
    p = np.random.default_rng(3).normal(size=model.n_params) * 1e-5
    fitted = FittedModel.zero(model)
    fitted.params.values[:] = p
    fitted.held = {"Z": -50.0}
    q = np.array([[100.0, -80.0, -150.0], [-200.0, 40.0, 90.0]])
    q_held = q.copy()
    q_held[:, 2] = -50.0
    params = dict(zip(model.param_names, p))
    ctx = {"feed": 0.0, "tool_length": machine.tool_length}
    dev_held = np.array([reference_deviation(machine, params, qq, ctx)[:3] for qq in q_held])
    dev_own = np.array([reference_deviation(machine, params, qq, ctx)[:3] for qq in q])
    assert np.abs(dev_own - dev_held).max() > 1e-4          # the extrapolation would differ
    nominal = q.copy()                                        # xfyz: the tip sits at (x, y, z)
    pts = predicted_points(fitted, q, np.zeros(2), np.zeros((2, 3)))
    np.testing.assert_allclose(pts - nominal, dev_held, rtol=0, atol=1e-10)
    np.testing.assert_allclose(model_errors(fitted, q)[0][:, :3], dev_held, rtol=0, atol=1e-10)
