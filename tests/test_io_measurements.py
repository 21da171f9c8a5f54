"""Measurement file readers (SPEC section 3): units, context, kinds, malformed files, writer, runs."""
import csv
import math
from pathlib import Path

import numpy as np
import pytest

from mtcomp import InputError, load_machine
from mtcomp.measurement.files import (BallbarData, CmmData, LaserData, PointsData, ThermalData,
                                    VelocityData, file_unit_scale, group_runs, read_measurements,
                                    split_runs, write_csv_with_columns)

REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"


def _write(tmp_path, text, name="m.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


POINTS = """x_mm,y_mm,z_mm,a_deg,c_deg,dx_um,dy_um,dz_um,tool_mm,feed_mm_min,dir_x,t_s,run,spindle_rpm,temp_spindle_c,note
10,20,30,90,-45,1.5,,-3,50,1200,-1,5,2,3000,21.5,first
0,0,0,0,0,,2,,,,1,,,,,second
"""


def test_points_units_context_and_verbatim_rows(tmp_path):
    d = read_measurements(_write(tmp_path, POINTS))
    assert isinstance(d, PointsData) and d.kind == "points" and len(d) == 2
    np.testing.assert_allclose(d.xyz, [[10, 20, 30], [0, 0, 0]], rtol=0, atol=0)
    # 90 deg, -45 deg in rad; b_deg absent -> 0
    np.testing.assert_allclose(d.abc[0], [math.pi / 2, 0.0, -math.pi / 4], rtol=1e-15, atol=0)
    assert d.rotary_columns == ("a_deg", "c_deg")
    # um -> mm; blank -> NaN (not measured)
    np.testing.assert_allclose(d.deviation[0], [0.0015, np.nan, -0.003], rtol=1e-15, atol=0)
    assert np.isnan(d.deviation[1, [0, 2]]).all() and d.deviation[1, 1] == pytest.approx(0.002, rel=1e-15)
    machine = load_machine("xfyz")
    np.testing.assert_allclose(d.tool_lengths(machine), [50.0, machine.tool_length], rtol=0, atol=0)
    c = d.context
    np.testing.assert_allclose(c.feed, [1200, np.nan], rtol=0, atol=0)
    np.testing.assert_array_equal(c.dir_of("X"), [-1, 1])
    np.testing.assert_array_equal(c.dir_of("Y"), [0, 0])
    np.testing.assert_array_equal(c.run, [2, -1])
    np.testing.assert_allclose(c.t, [5, np.nan], rtol=0, atol=0)
    np.testing.assert_allclose(c.spindle_rpm, [3000, np.nan], rtol=0, atol=0)
    np.testing.assert_allclose(c.temperatures["spindle"], [21.5, np.nan], rtol=0, atol=0)
    np.testing.assert_array_equal(d.row, [1, 2])
    assert d.header[-1] == "note" and d.rows[1][-1] == "second" and d.rows[0][5] == "1.5"
    assert d.prediction_columns == ("pred_dx_um", "pred_dy_um", "pred_dz_um")


def test_points_axis_positions_follow_machine_order(tmp_path):
    d = read_measurements(_write(tmp_path, POINTS))
    q = d.axis_positions(load_machine("cafxyz"))  # X Y Z A C
    np.testing.assert_allclose(q[0], [10, 20, 30, math.pi / 2, -math.pi / 4], rtol=1e-15, atol=0)
    # no c_deg column on a machine with C: taken at 0
    p = _write(tmp_path, "x_mm,y_mm,z_mm,a_deg,dz_um\n1,2,3,30,4\n", "a.csv")
    q = read_measurements(p).axis_positions(load_machine("cafxyz"))
    np.testing.assert_allclose(q, [[1, 2, 3, math.radians(30), 0.0]], rtol=1e-15, atol=0)
    # a rotary value on a machine without that axis is refused, naming the row
    with pytest.raises(InputError, match=r"row 1: column a_deg: machine .* has no A axis"):
        read_measurements(p).axis_positions(load_machine("xfyz"))
    # ... but an all-zero column is harmless
    p0 = _write(tmp_path, "x_mm,y_mm,z_mm,b_deg,dz_um\n1,2,3,0,4\n", "b.csv")
    np.testing.assert_allclose(read_measurements(p0).axis_positions(load_machine("xfyz")), [[1, 2, 3]],
                               rtol=0, atol=0)


def test_points_normal_deviation_and_normal_check(tmp_path):
    s = 1 / math.sqrt(2)
    d = read_measurements(_write(tmp_path, f"x_mm,y_mm,z_mm,dn_um,nx,ny,nz,tool_mm\n0,0,0,2.5,{s},{s},0,50\n"))
    assert isinstance(d, PointsData)
    np.testing.assert_allclose(d.normal_deviation, [0.0025], rtol=1e-15, atol=0)
    assert d.prediction_columns[-1] == "pred_dn_um"
    with pytest.raises(InputError, match=r"m\.csv: row 2: normal nx,ny,nz has length 1\.01"):
        read_measurements(_write(tmp_path, "x_mm,y_mm,z_mm,dn_um,nx,ny,nz,tool_mm\n"
                                           "0,0,0,1,0,0,1,0\n0,0,0,1,0,0,1.01,0\n"))
    with pytest.raises(InputError, match=r"row 1: dn_um is given but the normal"):
        read_measurements(_write(tmp_path, "x_mm,y_mm,z_mm,dn_um,nx,ny,nz,tool_mm\n0,0,0,1,,,,0\n"))
    # within the tolerance 1e-3: accepted
    read_measurements(_write(tmp_path, "x_mm,y_mm,z_mm,dn_um,nx,ny,nz,tool_mm\n0,0,0,1,0,0,1.0009,0\n"))


LASER = """axis,component,target_mm,target_deg,dir,run,value_um,value_urad,y_mm,z_mm,optic_x_mm,seq
X,EXX,100,,1,1,2.5,,50,,,7
X,EBX,100,,-1,1,,12,50,10,30,8
C,ECC,,90,1,3,,-4,,,,9
C,EZC,,-30,-1,3,0.7,,,,,10
"""


def test_laser_units_and_context(tmp_path):
    d = read_measurements(_write(tmp_path, LASER))
    assert isinstance(d, LaserData)
    np.testing.assert_array_equal(d.axis, ["X", "X", "C", "C"])
    np.testing.assert_array_equal(d.component, ["EXX", "EBX", "ECC", "EZC"])
    np.testing.assert_array_equal(d.angular, [False, True, True, False])
    np.testing.assert_allclose(d.target, [100, 100, math.pi / 2, -math.pi / 6], rtol=1e-15, atol=0)
    np.testing.assert_allclose(d.value, [2.5e-3, 12e-6, -4e-6, 0.7e-3], rtol=1e-15, atol=0)
    np.testing.assert_array_equal(d.dir, [1, -1, 1, -1])
    np.testing.assert_array_equal(d.run, [1, 1, 3, 3])
    np.testing.assert_array_equal(d.seq, [7, 8, 9, 10])
    np.testing.assert_allclose(d.optic[:, 0], [0, 30, 0, 0], rtol=0, atol=0)
    # `dir` is the approach direction of the moving axis only
    np.testing.assert_array_equal(d.context.dir_of("X"), [1, -1, 0, 0])
    np.testing.assert_array_equal(d.context.dir_of("C"), [0, 0, 1, -1])
    q = d.axis_positions(load_machine("cafxyz"))
    np.testing.assert_allclose(q[:, 0], [100, 100, 0, 0], rtol=0, atol=0)
    np.testing.assert_allclose(q[:, 1], [50, 50, 0, 0], rtol=0, atol=0)
    np.testing.assert_allclose(q[:, 2], [0, 10, 0, 0], rtol=0, atol=0)
    np.testing.assert_allclose(q[:, 4], [0, 0, math.pi / 2, -math.pi / 6], rtol=1e-15, atol=0)
    with pytest.raises(InputError, match=r"row 3: axis C: machine '.*' \(XFYZ\) has no such axis"):
        d.axis_positions(load_machine("xfyz"))
    assert d.prediction_columns == ("pred_value_um", "pred_value_urad")


@pytest.mark.parametrize("row, msg", [
    ("X,EQX,1,1,1,2", r"row 2: column component: 'EQX' is not an ISO 230-1 component"),
    ("X,EXY,1,1,1,2", r"row 2: column component: EXY is an error of axis Y, but this row moves axis X"),
    ("X,EAX,1,1,1,2", r"row 2: units mixed: component EAX is angular and takes value_urad"),
    ("X,EXX,1,2,1,2", r"row 2: column dir: '2' is not an approach direction"),
    ("X,EXX,1,0,1,2", r"row 2: column dir: '0' is not an approach direction"),
    ("X,EXX,1,down,1,2", r"row 2: column dir: 'down' is not an approach direction: write \+1"),
    ("X,EXX,1,Fwd,1,2", r"row 2: column dir: 'Fwd' is not an approach direction: write \+1"),
    ("X,EXX,1,,1,2", r"row 2: column dir is blank"),
    ("X,EXX,1,1,,2", r"row 2: column run is blank"),
    ("X,EXX,1,1,1.5,2", r"row 2: column run: '1.5' is not a whole number"),
    ("X,EXX,,1,1,2", r"row 2: column target_mm is blank"),
    ("X,EXX,abc,1,1,2", r"row 2: column target_mm: 'abc' is not a number"),
    ("X,EXX,nan,1,1,2", r"row 2: column target_mm: 'nan' is not a finite number"),
    ("X,EXX,1,1,1,inf", r"row 2: column value_um: 'inf' is not a finite number"),
    ("Q,EXX,1,1,1,2", r"row 2: column axis: 'Q' is not an axis"),
    ("C,ECC,1,1,1,2", r"row 2: missing column target_deg"),
    ("X,EXX,1,1,1", r"row 2: 5 cells but the header has 6 columns"),
])
def test_laser_malformed_rows(tmp_path, row, msg):
    p = _write(tmp_path, f"axis,component,target_mm,dir,run,value_um\nX,EXX,0,1,1,1\n{row}\n")
    with pytest.raises(InputError, match=msg):
        read_measurements(p)


def test_negative_feed_is_refused_blank_feed_is_not(tmp_path):
    head = "axis,component,target_mm,dir,run,value_um,feed_mm_min\n"
    p = _write(tmp_path, head + "X,EXX,0,1,1,1,1000\nX,EXX,10,-1,1,2,-1000\n")
    with pytest.raises(InputError, match=r"row 2: column feed_mm_min must not be negative"):
        read_measurements(p)
    p = _write(tmp_path, head + "X,EXX,0,1,1,1,1000\nX,EXX,10,-1,1,2,\n")
    feed = read_measurements(p).context.feed
    assert feed[0] == 1000.0 and np.isnan(feed[1])


def test_laser_units_mixed_the_other_way(tmp_path):
    p = _write(tmp_path, "axis,component,target_mm,dir,run,value_urad\nX,EYX,0,1,1,3\n")
    with pytest.raises(InputError, match=r"row 1: units mixed: component EYX is translational and takes "
                                         r"value_um, but value_urad is given"):
        read_measurements(p)


@pytest.mark.parametrize("text, msg", [
    ("", r"empty file"),
    ("\n\n", r"empty file"),
    ("axis,component,target_mm,dir,run,value_um\n", r"no data rows"),
    ("axis,component,target_mm,dir,value_um\nX,EXX,0,1,1\n", r"missing column run \(a laser file needs"),
    ("axis,component,dir,run,value_um\nX,EXX,1,1,1\n", r"missing column target_mm or target_deg"),
    ("axis,component,target_mm,dir,run\nX,EXX,0,1,1\n", r"missing column value_um or value_urad"),
    ("x_mm,y_mm,dx_um\n1,2,3\n", r"missing column z_mm \(a points file needs"),
    ("x_mm,y_mm,z_mm,dx_um\n1,2,3,x4\n", r"row 1: column dx_um: 'x4' is not a number"),
    ("x_mm,y_mm,z_mm,dx_um\n1,,3,4\n", r"row 1: column y_mm is blank; a value is required"),
    ("x_mm,y_mm,z_mm,dx_um,dir_y\n1,2,3,4,+2\n", r"row 1: column dir_y: '\+2' is not an approach"),
    ("x_mm,x_mm,z_mm,dx_um\n1,2,3,4\n", r"row 0: column 'x_mm' appears twice"),
    ("x_mm,,z_mm,dx_um\n1,2,3,4\n", r"row 0: header column 2 has no name"),
    ("foo,bar\n1,2\n", r"unknown kind of measurement file: .*expected points: x_mm"),
    ("x_mm,y_mm,z_mm,nx,ny,nz,dn_um\n0,0,0,0,0,1,1\n", r"ambiguous kind: .* add a column 'kind'"),
    ("x_mm,y_mm,z_mm,dx_um,length_mm\n0,0,0,1,1\n", r"ambiguous kind: columns of several kinds: "
                                                    r"ballbar \(length_mm\), points \(dx_um\)"),
    ("t_s,temp_a_c\n0,20\n", r"unknown kind"),
    ("t_s,disp_a_um\n,1\n", r"row 1: column t_s is blank"),
])
def test_malformed_files(tmp_path, text, msg):
    p = _write(tmp_path, text, "bad.csv")
    with pytest.raises(InputError, match=msg) as info:
        read_measurements(p)
    assert info.value.path == str(p)
    assert "\n" not in info.value.one_line()


def test_missing_file_and_folder(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_measurements(tmp_path / "nope.csv")
    with pytest.raises(InputError, match="is a folder"):
        read_measurements(tmp_path)


def test_blank_lines_keep_row_numbers_of_file_lines(tmp_path):
    # a blank line still counts: row = file line - 1, so the error points at the right line
    p = _write(tmp_path, "x_mm,y_mm,z_mm,dx_um\n1,2,3,4\n\n1,2,3,oops\n")
    with pytest.raises(InputError, match=r"row 3: column dx_um"):
        read_measurements(p)
    d = read_measurements(_write(tmp_path, "x_mm,y_mm,z_mm,dx_um\n1,2,3,4\n\n1,2,3,5\n"))
    np.testing.assert_array_equal(d.row, [1, 3])


def test_kind_column_and_argument_resolve_cmm_or_points(tmp_path):
    text = "x_mm,y_mm,z_mm,nx,ny,nz,dn_um{k}\n5,6,7,1,0,0,-2{v}\n"
    d = read_measurements(_write(tmp_path, text.format(k=",kind", v=",cmm")))
    assert isinstance(d, CmmData)
    np.testing.assert_allclose(d.normal_deviation, [-0.002], rtol=1e-15, atol=0)
    np.testing.assert_allclose(d.xyz, [[5, 6, 7]], rtol=0, atol=0)
    assert isinstance(read_measurements(_write(tmp_path, text.format(k=",kind", v=",points"))), PointsData)
    assert isinstance(read_measurements(_write(tmp_path, text.format(k="", v="")), kind="cmm"), CmmData)
    with pytest.raises(InputError, match="unknown measurement kind 'foo'"):
        read_measurements(_write(tmp_path, text.format(k="", v="")), kind="foo")


def test_ballbar(tmp_path):
    d = read_measurements(_write(tmp_path, "x_mm,y_mm,z_mm,c_deg,table_ball_x_mm,table_ball_y_mm,"
                                 "table_ball_z_mm,tool_ball_x_mm,tool_ball_y_mm,tool_ball_z_mm,length_mm\n"
                                 "100,0,0,180,0,0,50,0,0,10,100.0021\n"))
    assert isinstance(d, BallbarData)
    np.testing.assert_allclose(d.table_ball, [[0, 0, 50]], rtol=0, atol=0)
    np.testing.assert_allclose(d.tool_ball, [[0, 0, 10]], rtol=0, atol=0)
    np.testing.assert_allclose(d.length, [100.0021], rtol=0, atol=0)
    np.testing.assert_allclose(d.axis_positions(load_machine("cbfxyz")), [[100, 0, 0, 0, math.pi]],
                               rtol=1e-15, atol=0)


def test_thermal(tmp_path):
    d = read_measurements(_write(tmp_path, "t_s,spindle_rpm,disp_ch1_um,disp_ch2_um,temp_bed_c\n"
                                 "0,0,1.5,,20\n15,2500,-3,4,20.5\n"))
    assert isinstance(d, ThermalData)
    np.testing.assert_allclose(d.t, [0, 15], rtol=0, atol=0)
    np.testing.assert_allclose(d.context.t, [0, 15], rtol=0, atol=0)
    np.testing.assert_allclose(d.channels["ch1"], [0.0015, -0.003], rtol=1e-15, atol=0)
    np.testing.assert_allclose(d.channels["ch2"], [np.nan, 0.004], rtol=1e-15, atol=0)
    np.testing.assert_allclose(d.context.spindle_rpm, [0, 2500], rtol=0, atol=0)
    np.testing.assert_allclose(d.context.temperatures["bed"], [20, 20.5], rtol=0, atol=0)
    assert d.prediction_columns == ("pred_disp_ch1_um", "pred_disp_ch2_um")


def test_velocity_and_rotation_centre_of_a_rigid_motion(tmp_path):
    # known truth: the table translates at V0 along X and turns at w about O (seed 000, eq. 1)
    rng = np.random.default_rng(4)
    rows = []
    truth = []
    for i in range(5):
        feed = 240.0
        w = rng.uniform(1e-3, 5e-3) * rng.choice([-1, 1])
        o = rng.uniform(-300, 300, 2)
        m, n = rng.uniform(-200, 200, 2), rng.uniform(-200, 200, 2)
        vel = [np.array([feed, 0.0]) + w * np.array([-(p[1] - o[1]), p[0] - o[0]]) for p in (m, n)]
        cells = [float(v) for v in (*m, *vel[0], *n, *vel[1])]
        rows.append(f"X,{feed},{10.0 * i}," + ",".join(repr(v) for v in cells) + ",1")
        truth.append(o)
    text = ("axis,feed_mm_min,x_mm,m_x_mm,m_y_mm,m_vx_mm_min,m_vy_mm_min,n_x_mm,n_y_mm,n_vx_mm_min,"
            "n_vy_mm_min,dir_x\n" + "\n".join(rows) + "\n")
    d = read_measurements(_write(tmp_path, text))
    assert isinstance(d, VelocityData)
    np.testing.assert_allclose(d.position, [0, 10, 20, 30, 40], rtol=0, atol=0)
    np.testing.assert_allclose(d.context.feed, 240.0, rtol=0, atol=0)
    np.testing.assert_allclose(d.rotation_centre(), truth, rtol=0, atol=1e-6)
    with pytest.raises(InputError, match=r"row 1: column feed_mm_min must not be negative"):
        read_measurements(_write(tmp_path, text.replace("X,240.0", "X,-240.0", 1)))
    # read in the bed's sense (the table's own motion: every velocity negated, dir_x kept): taken in
    # the axis's own sense, the same rotation centre
    head, *body = text.strip().split("\n")
    flipped = [",".join(c if j not in (5, 6, 9, 10) else repr(-float(c)) for j, c in enumerate(r.split(",")))
               for r in body]
    b = read_measurements(_write(tmp_path, "\n".join([head] + flipped) + "\n", "bed.csv"))
    assert b.bed_sense and not d.bed_sense
    np.testing.assert_allclose(np.hstack([b.m_v, b.n_v]), np.hstack([d.m_v, d.n_v]), rtol=0, atol=0)
    np.testing.assert_allclose(b.rotation_centre(), truth, rtol=0, atol=1e-6)
    # the velocity along the moving axis is the feed: another axis's, or a sign against dir_x, is refused
    first = rows[0].split(",")
    for k, v, msg in ((11, "-1", r"row 1: column m_vx_mm_min: 2\d\d.* mm/min, but the table moves along X at "
                                 r"-240 mm/min in the axis's own sense \(feed_mm_min and dir_x\)"),
                      # no dir_x: the sign is the velocities', and both points must agree with it
                      (11, "", r"row 1: column n_vx_mm_min: 2\d\d.* mm/min, but the table moves along X at "
                               r"-240 mm/min in the axis's own sense \(feed_mm_min, signed by the velocities\)"),
                      (5, "0.0", r"row 1: column m_vx_mm_min: 0 mm/min, but the table moves along X at 240"),
                      (0, "Z", r"row 1: column axis: Z: a velocity file's table moves along X or Y")):
        bad = first.copy()
        bad[k] = v
        if k == 11 and v == "":                # M read backwards: -240 and N +240 sum to 0 -> sign +
            bad[5] = repr(-float(first[5]) - 1.0)
        with pytest.raises(InputError, match=msg):
            read_measurements(_write(tmp_path, text.replace(rows[0], ",".join(bad), 1)))
    with pytest.raises(InputError, match=r"row 1: column feed_mm_min must be positive"):
        read_measurements(_write(tmp_path, text.replace("X,240.0", "X,0.0", 1)))
    with pytest.raises(InputError, match=r"row 1: missing column y_mm \(position of moving axis Y\)"):
        read_measurements(_write(tmp_path, text.replace("X,240.0", "Y,240.0", 1)))


def test_group_and_split_runs(tmp_path):
    text = "x_mm,y_mm,z_mm,dx_um,run\n" + "".join(f"{i},0,0,{i * 10},{i % 3}\n" for i in range(9))
    d = read_measurements(_write(tmp_path, text))
    groups = group_runs(d)
    assert list(groups) == [0, 1, 2]
    np.testing.assert_allclose(groups[1].xyz[:, 0], [1, 4, 7], rtol=0, atol=0)
    np.testing.assert_allclose(groups[1].deviation[:, 0], [0.01, 0.04, 0.07], rtol=1e-15, atol=0)
    np.testing.assert_array_equal(groups[1].row, [2, 5, 8])
    assert groups[1].rows[0][0] == "1" and len(groups[1].rows) == 3
    np.testing.assert_array_equal(groups[1].context.run, [1, 1, 1])
    fit, held = split_runs(d, [2])
    np.testing.assert_array_equal(held.row, [3, 6, 9])
    np.testing.assert_array_equal(fit.row, [1, 2, 4, 5, 7, 8])
    assert len(fit) + len(held) == len(d)


def test_write_csv_with_columns(tmp_path):
    p = _write(tmp_path, '  x_mm ,y_mm,z_mm,dx_um,note\n1.50,2,3,,"a, b"\n4,5,6,7,c\n')
    d = read_measurements(p)
    out = tmp_path / "pred.csv"
    write_csv_with_columns(out, d, {"pred_dx_um": np.array([0.0012, np.nan]),
                                    "pred_a_deg": np.array([math.pi, 0.0])})
    with open(out, newline="") as f:
        got = list(csv.reader(f))
    assert got[0] == ["  x_mm ", "y_mm", "z_mm", "dx_um", "note", "pred_dx_um", "pred_a_deg"]
    assert got[1] == ["1.50", "2", "3", "", "a, b", "1.2", "180"]
    assert got[2] == ["4", "5", "6", "7", "c", "", "0"]
    with pytest.raises(InputError, match="overwrite an input"):
        write_csv_with_columns(p, d, {"pred_dx_um": np.zeros(2)})
    with pytest.raises(InputError, match="already has a column dx_um"):
        write_csv_with_columns(tmp_path / "x.csv", d, {"dx_um": np.zeros(2)})
    assert not (tmp_path / "x.csv").exists()
    assert sorted(f.name for f in tmp_path.iterdir()) == ["m.csv", "pred.csv"]


def test_file_unit_scale():
    assert file_unit_scale("pred_value_urad") == 1e6
    assert file_unit_scale("pred_dz_um") == 1e3
    assert file_unit_scale("feed_mm_min") == 1.0
    assert file_unit_scale("c_deg") == pytest.approx(57.29577951308232, rel=1e-15, abs=0)
    with pytest.raises(ValueError):
        file_unit_scale("pred_dx")


def test_real_thermal_file():
    from real_data import THERMAL as path
    if not path.exists():
        pytest.skip(f"real data not found at {path}")
    d = read_measurements(path)
    assert isinstance(d, ThermalData) and len(d) == 11115
    assert sorted(d.channels) == [f"ch{i}" for i in range(1, 6)]
    assert len(d.context.temperatures) == 16
    np.testing.assert_allclose(np.diff(d.t), 15.0, rtol=0, atol=1e-9)
    # README: displacements reach about -71 um
    lowest_um = min(np.nanmin(v) for v in d.channels.values()) * 1e3
    assert -75 < lowest_um < -65
    assert set(np.unique(d.context.spindle_rpm)) >= {0.0, 1250.0, 2500.0, 3750.0, 5000.0}


def test_binary_and_non_utf8_files(tmp_path):
    p = tmp_path / "bin.csv"
    p.write_bytes(b"x_mm,y_mm\n\xff\xfe\x00\x01\n")
    with pytest.raises(InputError, match="not a UTF-8 text file"):
        read_measurements(p)
    p.write_bytes(b"x_mm,y_mm,z_mm,dx_um\n1,2,3,\x004\n")
    with pytest.raises(InputError, match=r"bin\.csv: row 1: column dx_um: .* is not a number"):
        read_measurements(p)


def test_identify_says_a_velocity_file_meets_a_model_without_a_rotation_centre(tmp_path, capsys):
    """The command's base model has no instantaneous rotation centre: a new user's velocity file
    put the centre's motion with feed into the pitch errors, and only a warning about files of
    different machines followed. The note names the cause and diagnose."""
    from mtcomp.cli import main
    rows = [f"X,{feed},{x},0,0,{feed},0,100,50,{feed},0" for feed in (200, 400) for x in (0, 50, 100)]
    text = ("axis,feed_mm_min,x_mm,m_x_mm,m_y_mm,m_vx_mm_min,m_vy_mm_min,n_x_mm,n_y_mm,n_vx_mm_min,"
            "n_vy_mm_min\n" + "\n".join(rows) + "\n")
    src = _write(tmp_path, text)
    assert main(["identify", "xfyz", str(src), "-o", str(tmp_path / "m.json")]) == 0
    err = capsys.readouterr().err
    assert f"note: {src}: identify fits the machine's base model, which has no instantaneous " \
           "rotation centre" in err and "mtcomp diagnose" in err


def test_a_velocity_file_of_an_axis_that_carries_the_tool_is_noted(tmp_path, capsys):
    """The two-point method measures a table: on cbfxyz X carries the spindle, and a file of X
    velocities was read without a word (a new user's file of an X table measured on another
    topology). xfyz's X carries the table: no note."""
    from mtcomp import load_machine
    from mtcomp.commands import note_outside_travel
    rows = [f"X,300,{x},0,0,300,0,100,50,300,0" for x in (0, 50, 100)]
    src = _write(tmp_path, "axis,feed_mm_min,x_mm,m_x_mm,m_y_mm,m_vx_mm_min,m_vy_mm_min,n_x_mm,"
                 "n_y_mm,n_vx_mm_min,n_vy_mm_min\n" + "\n".join(rows) + "\n")
    for machine, said in (("cbfxyz", True), ("xfyz", False)):
        capsys.readouterr()
        note_outside_travel(load_machine(machine), [read_measurements(src)])
        err = capsys.readouterr().err
        assert ("axis X carries the tool, not the table" in err) == said, (machine, err)
