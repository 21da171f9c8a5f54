"""A turn of the whole machine against the workpiece frame that the data leave open goes by the
convention: X is the reference axis, so the slopes of EYX, EZX and EZY are zero and the squareness
C0Y (B0Z, A0Z) carries the angle between the axes.

With a tracker's frame fitted, the slope of X's straightness in Y together with C0Y and the frame
turned back changes no reading. A new user's router (true C0Y 30 urad; laser runs and a tracker
grid) came out with EYX sloping by -26 urad and C0Y "not determined", and the compensated part was
turned against the X travel. This campaign, before: C0Y not determined, the compensated part
turned by 3.4 urad.

Oracle that shares no code with the model: the independent truth machine (tests/truth), C0Y = 30
urad and nothing else, its tracker frame turned by 5 to 50 urad per component; the compensated
part's error is the truth's deviation less the model's, and its turn about Z is fitted by hand."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp.identification.fit import identify
from mtcomp.identification.predict import predict_readings
from mtcomp.identification.report import component_ranges
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from truth import TruthMachine
from truth import campaigns as tc

C0Y_URAD = 30.0
Z = -50.0
#: a router whose axes run from 0 (the workpiece origin at a corner of the travel), as the user's
ROUTER = """name = "router"
topology = "XFYZ"
tool_length_mm = 40.0
[axes.X]
travel_mm = [0.0, 600.0]
[axes.Y]
travel_mm = [0.0, 400.0]
[axes.Z]
travel_mm = [-100.0, 0.0]
"""
CENTRE = (300.0, 200.0, Z)


def _campaign(folder, seed: int, tracker: bool | None = True, c0y_urad: float = C0Y_URAD,
              centre=CENTRE):
    """Laser positioning runs of X and Y, a circle in XY (about ``centre``) and a tracker grid
    (frame fitted) on the truth machine with C0Y = ``c0y_urad``. ``tracker`` False: a straightness
    run of X in Y (its optic's slope fitted) in place of the grid; None: neither. Returns (truth,
    fitted result)."""
    rng = np.random.default_rng(seed)
    machine = folder / "router.toml"
    machine.write_text(ROUTER)
    truth = TruthMachine.zero(str(machine))
    truth.squareness["C0Y"] = c0y_urad * 1e-6
    files = [tc.laser(truth, folder / "laser_x.csv", rng, "X", components=["EXX"], n_runs=2,
                      static={"Y": 200.0, "Z": Z}).path,
             tc.laser(truth, folder / "laser_y.csv", rng, "Y", components=["EYY"], n_runs=2,
                      static={"X": 300.0, "Z": Z}).path,
             tc.ballbar_circles(truth, folder / "ballbar.csv", rng, planes=("XY",), radius_mm=150.0,
                                centre_mm=centre, n_points=36).path,
             tc.points(truth, folder / "tracker.csv", rng, grid=(5, 4, 3), directions=(1,),
                       setup=True).path if tracker else
             tc.laser(truth, folder / "straight_yx.csv", rng, "X", components=["EYX"], n_runs=2,
                      static={"Y": 200.0, "Z": Z}).path]
    files = files[:-1] if tracker is None else files
    return truth, identify(load_machine(str(machine)), [read_measurements(p) for p in files])


def _grid_errors(truth, fitted, folder):
    """(points (N, 2) mm, model deviation (N, 3) um, truth deviation (N, 3) um) at Z on a grid."""
    xs, ys = np.meshgrid(np.linspace(0.0, 600.0, 7), np.linspace(0.0, 400.0, 5))
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    path = folder / "grid.csv"
    with open(path, "w") as f:
        f.write("x_mm,y_mm,z_mm,dx_um,dy_um,dz_um\n"
                + "".join(f"{x:g},{y:g},{Z:g},,,\n" for x, y in pts))
    cols = predict_readings(fitted, read_measurements(path)).columns
    model = np.column_stack([np.asarray(cols[f"pred_d{c}_um"], float) for c in "xyz"])
    q = np.column_stack([pts, np.full(len(pts), Z)])
    return pts, model, truth.true_deviation(q)[0] * 1e3


def _turn_about_z_urad(pts, err) -> float:
    """The least-squares turn w (urad) of err (N, 2) um about Z: err = t + w (-y, x)."""
    n = len(pts)
    A = np.zeros((2 * n, 3))
    A[0::2, 0] = 1.0
    A[1::2, 1] = 1.0
    A[0::2, 2] = -pts[:, 1] * 1e-3
    A[1::2, 2] = pts[:, 0] * 1e-3
    sol = np.linalg.lstsq(A, err[:, :2].reshape(-1), rcond=None)[0]
    return float(sol[2])


def _file_sd(params, name: str) -> float:
    """MODEL.json's standard error of parameter ``name`` (file units; NaN: none)."""
    i = params.index(name)
    return float(params.stderr[i] * params.specs[i].to_file)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rigid")
    return (folder, *_campaign(folder, seed=8))


def test_a_turn_the_data_leave_open_goes_to_the_squareness_not_to_the_part(fitted):
    tmp_path, truth, result = fitted
    c0y, sd = result.value("C0Y")
    assert np.isfinite(sd) and sd < 10.0
    # 3 sd: over seeds 1-8 of this campaign (error / sd) has an rms of 1.16, so the sd is honest and
    # seed 8's -2.3 (29.10 +- 0.39) is a draw a 2-sd bound misses one time in twenty
    assert abs(c0y - C0Y_URAD) < 3.0 * sd
    pts, model, actual = _grid_errors(truth, result.fitted_model, tmp_path)
    # X's straightness in Y along the X travel at y = 0: no slope
    row = np.abs(pts[:, 1] - 200.0) < 1e-9
    slope = np.polyfit(pts[row, 0], model[row, 1], 1)[0] * 1e3      # um/m = urad
    assert abs(slope) < 2.0
    # the compensated part (truth less model, to first order) is not turned against the X travel
    assert abs(_turn_about_z_urad(pts, actual - model)) < 2.0
    # the oracle's own figure: dx = -y C0Y over the grid turns by C0Y var(y) / (var(x) + var(y))
    vx, vy = np.var(pts[:, 0]), np.var(pts[:, 1])
    assert abs(_turn_about_z_urad(pts, actual) - C0Y_URAD * vy / (vx + vy)) < 0.5


def test_the_report_prints_the_slope_of_a_straightness_no_squareness_carries(fitted):
    """EYX made a straight line of 20 urad (hand-set coefficients on a fine grid): the report's
    range about the line is 0 and the slope line says 20 urad; EXY (slope carried) says none."""
    from dataclasses import replace
    from mtcomp.identification.report import component_lines
    from mtcomp.models.basis import axis_spline
    model = fitted[2].fitted_model
    ax = model.machine.axis("X")
    spline = axis_spline(ax)
    s = np.linspace(spline.lo, spline.hi, 201)
    phi = np.array(spline.functions(s, False)).T
    c = np.linalg.lstsq(phi, 20e-6 * (s - s.mean()), rcond=None)[0]          # mm
    params = model.params.copy()
    for k, j in enumerate(spline.kept(False)):
        params.values[params.index(f"EYX_b{j}")] = c[k]
    turned = replace(model, params=params)
    eyx = [r for r in component_ranges(turned)[0] if r.component == "EYX"][0]
    assert eyx.slope == pytest.approx(20.0, abs=0.05) and eyx.range < 0.01
    lines = component_lines(turned)
    assert any("EYX" in ln and "slope 20." in ln for ln in lines)
    assert not any("EXY" in ln and "slope" in ln for ln in lines)


def test_without_a_tracker_the_turn_is_open_too_and_goes_by_the_convention(tmp_path):
    """Lasers (X and Y positioning, X's straightness in Y with its optic's slope fitted) and the
    circle, no points file: the straightness run's slope is a set-up, so a turn of the machine with
    the optic turned back changes no reading either, and the convention holds (a new user's VMC:
    C0Y -7.4 urad with EYX sloping by -7.7 urad where the truth had neither, predictions of dy 1.31
    um rms off). Before, the convention held only with a points or cmm frame fitted: C0Y 19.0 urad,
    EYX sloping by -10.6 urad, the compensated part turned by 10.7 urad. Now C0Y 30.4 urad (not
    determined alone: at one height a roll of Y, which no laser names and which is held at zero,
    shifts x as C0Y does), EYX's slope 0.02 urad, the part turned by 0.15 urad."""
    truth, result = _campaign(tmp_path, seed=8, tracker=False)
    assert abs(result.value("C0Y")[0] - C0Y_URAD) < 2.0
    pts, model, actual = _grid_errors(truth, result.fitted_model, tmp_path)
    row = np.abs(pts[:, 1] - 200.0) < 1e-9
    assert abs(np.polyfit(pts[row, 0], model[row, 1], 1)[0] * 1e3) < 1.0        # urad
    assert abs(_turn_about_z_urad(pts, actual - model)) < 1.0


def test_lasers_and_one_circle_give_the_squareness_with_its_standard_error_and_no_slope(tmp_path):
    """A job shop's campaign: laser positioning runs of X and Y and one ball-bar circle in XY, no
    straightness run, no points file; the truth's only error a squareness C0Y of 20 urad. The circle
    reads the angle between the axes; the turn of the whole machine is open and goes by the
    convention (EYX's slope zero), and the roll of Y and the pitch and roll of X that no laser names
    are held at zero, so C0Y is determined on those two rules and carries a standard error. Before:
    C0Y -14.5 urad 'not determined' (the shop's truth -20), the rest of the angle in a slope of EYX
    (dy +-1.1 um at X's ends). Here C0Y 19.9 +- 0.53 urad, EYX's slope below 1e-8 urad; on the old
    code C0Y 11.7 urad with no standard error and EYX sloping by -7.7 urad; with the convention but
    the report counting C0Y undetermined for its combinations with the held rolls, "not determined"."""
    truth, result = _campaign(tmp_path, seed=1, tracker=None, c0y_urad=20.0)
    # as the printed report gives it, MODEL.json's standard error
    c0y, sd, status = [(v.value, v.sd, v.status) for v in component_ranges(result.fitted_model)[1]
                       if v.name == "C0Y"][0]
    assert status == "fitted" and np.isfinite(sd) and sd < 2.0, (c0y, sd, status)
    assert abs(c0y - 20.0) < 3.0 * sd, (c0y, sd)
    assert sd == pytest.approx(_file_sd(result.fitted_model.params, "C0Y"), rel=1e-6)
    pts, model, _ = _grid_errors(truth, result.fitted_model, tmp_path)
    row = np.abs(pts[:, 1] - 200.0) < 1e-9
    assert abs(np.polyfit(pts[row, 0], model[row, 1], 1)[0] * 1e3) < 0.5        # urad


def test_a_circle_at_another_height_leaves_the_squarenesses_with_z_open(tmp_path):
    """The same shop's campaign with the circle 40 mm below the laser runs: the circle reads B0Z and
    A0Z only as a shift of its centre (the centre its file states, not the machine), so they stay
    "not determined" in the report and without a standard error in MODEL.json, while C0Y, read
    from the circle's shape, keeps its own. With the rigid-turn convention's first version the
    report gave B0Z and A0Z a standard error on the rolls held at zero (the shop's B0Z 10.1 +- 0.8
    urad where its truth is 0)."""
    truth, result = _campaign(tmp_path, seed=1, tracker=None, c0y_urad=20.0,
                              centre=(CENTRE[0], CENTRE[1], Z - 40.0))
    values = {v.name: v for v in component_ranges(result.fitted_model)[1]}
    params = result.fitted_model.params
    assert values["C0Y"].status == "fitted" and abs(values["C0Y"].value - 20.0) < 3.0 * values["C0Y"].sd
    for name in ("B0Z", "A0Z"):
        assert values[name].status == "undetermined", values[name]
        assert np.isnan(_file_sd(params, name)), name
