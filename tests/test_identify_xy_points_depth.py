"""A CMM's hole positions (dx, dy only, no dz) measure no depth: the model corrects none.

Two drilled plates on a table machine (XYFZ: the table X rides on the saddle Y), each hole's
centre measured in X and Y with the CMM aligned to the plate (a set-up turn about Z fitted per
plate), holes cut with tools of 100 and 200 mm at one depth. Nothing read Z. A roll of X turned
with the tool tip's height (-405 mm) moves Y in proportion to X, the same as a turn of the plates,
and moves Z by the roll times Y: kept open by the data, it was held where it predicted the least
error, and the part's holes got Z corrections (0.8 um on a user's VF-2, 20 um from a file given in
the part's frame). The data do not measure that roll, and no laser names it: it is held at zero
(docs/identification.md, "What the data do not determine stays at zero error", rule 3)."""
import csv
import re

import numpy as np

from mtcomp.cli import main
from truth import TruthMachine
from truth import campaigns as tc
from truth import profiles as P

MACHINE = """name = "vf2-like"
topology = "XYFZ"
tool_length_mm = 100.0
units = "mm"
[axes.X]
travel_mm = [-762.0, 0.0]
[axes.Y]
travel_mm = [-406.0, 0.0]
[axes.Z]
travel_mm = [-508.0, 0.0]
"""
ZDEPTH = -405.0


def _truth(machine_file) -> TruthMachine:
    truth = TruthMachine(str(machine_file))
    truth.squareness["C0Y"] = 25e-6
    truth.squareness["B0Z"] = 20e-6
    truth.squareness["A0Z"] = -10e-6
    truth.components["X"]["EXX"] = P.Linear(0.0, 12e-6)
    truth.components["Y"]["ECY"] = P.Linear(15e-6, 15e-6 / 406.0)
    return truth


def _plates(folder, machine_file, zdepth=ZDEPTH):
    truth = _truth(machine_file)
    rng = np.random.default_rng(6)
    files = []
    for k in range(2):
        res = tc.points(truth, folder / f"full_{k}.csv", rng, grid=(11, 7, 1), margin=0.18,
                        plane={"Z": zdepth}, tool_lengths_mm=(100.0, 200.0), directions=(1,),
                        noise_um=1.0)
        cols = {c: res.columns[c] for c in ("x_mm", "y_mm", "z_mm", "tool_mm", "dx_um", "dy_um")}
        files.append(str(tc.write_csv(folder / f"plate_{k}.csv", cols)))
    return files


PROGRAM = ("G21 G90 G17 G94\nT1 M6\nG54\nG0 X-225 Y-125\nG43 Z15 H1\n"
           "G98 G81 X-225 Y-125 Z-12 R5 F200\nX225 Y125\nX-225 Y125\nX225 Y-125\nG80\n"
           "T2 M6\nG0 X0 Y0\nG43 Z15 H2\nG98 G81 X0 Y0 Z-12 R5 F200\nX100 Y-100\nG80\nM30\n")


def _model(folder, zdepth):
    """(machine file, model file) of the two plates measured at machine depth ``zdepth``."""
    machine, model = folder / "m.toml", folder / "model.json"
    if not model.exists():                  # the second call compensates with the same model
        machine.write_text(MACHINE)
        files = _plates(folder, machine, zdepth)
        assert main(["identify", str(machine), *files, "-o", str(model)]) == 0
    return machine, model


def _compensated(folder, zdepth, *extra):
    """BLOCKS.csv rows of the part (G54 at Z -400: holes at machine Z -412) compensated with the
    model of the two plates measured at machine depth ``zdepth``."""
    machine, model = _model(folder, zdepth)
    prog = folder / "part.nc"
    prog.write_text(PROGRAM)
    offsets = folder / "offsets.toml"
    offsets.write_text("[work_offsets]\nG54 = {X = -381.0, Y = -203.0, Z = -400.0}\n"
                       "[tool_lengths]\nH1 = 100.0\nH2 = 200.0\n")
    report = folder / "b.csv"
    assert main(["compensate", str(machine), str(model), str(prog), "-o", str(folder / "c.nc"),
                 "--offsets", str(offsets), "--report", str(report), *extra]) == 0
    with open(report) as f:
        return list(csv.DictReader(f))


def _hole_errors_um(truth, rows, with_correction: bool) -> np.ndarray:
    """(n, 2) um: the X Y error of the tip at each hole's bottom on the independent machine,
    relative to the datum probed with the machine's 100 mm tool, less the best turn and shift in
    the plane (the plates' CMM alignment leaves the part's turn open); with or without the
    correction BLOCKS.csv gives (its positions are the corrected ones)."""
    g54 = np.array([-381.0, -203.0, -400.0])
    c = np.array([[float(r[k] or 0.0) for k in ("cx_um", "cy_um", "cz_um")] for r in rows]) * 1e-3
    q = np.array([[float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in rows]) + g54
    q = q if with_correction else q - c
    tool = np.array([100.0 if int(r["line"]) < 12 else 200.0 for r in rows])   # H1, then H2
    dev = truth.true_deviation(q, tool)[0] + (c if with_correction else 0.0)
    e = (dev - truth.true_deviation(g54[None, :], 100.0)[0][0])[:, :2] * 1e3
    x, y = q[:, 0] - q[:, 0].mean(), q[:, 1] - q[:, 1].mean()
    A = np.zeros((2 * len(q), 3))
    A[0::2, 0], A[1::2, 1], A[0::2, 2], A[1::2, 2] = 1.0, 1.0, -y * 1e-3, x * 1e-3
    r = e.ravel() - A @ np.linalg.lstsq(A, e.ravel(), rcond=None)[0]
    return r.reshape(-1, 2)


def test_xy_hole_positions_correct_no_depth(tmp_path):
    rows = [r for r in _compensated(tmp_path, ZDEPTH, "--extrapolate") if r["corrected"] == "1"]
    assert len(rows) >= 8, rows
    cz = np.array([float(r["cz_um"] or 0.0) for r in rows])
    # the X and Y errors are corrected: on the independent machine, the holes' errors (rigid motion
    # in the plane removed) fall to a small part of what they were ...
    truth = _truth(tmp_path / "m.toml")
    holes = [r for r in rows if abs(float(r["z_mm"]) + 12.0) < 0.01]
    before = _hole_errors_um(truth, holes, False)
    after = _hole_errors_um(truth, holes, True)
    rms = lambda e: float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))    # noqa: E731
    assert len(holes) >= 6 and rms(before) > 1.0, rms(before)
    assert rms(after) < 0.3 * rms(before), (rms(before), rms(after))
    # ... and Z, which no file read, is not (the old fit: up to 0.7 um at the corner holes)
    np.testing.assert_allclose(cz, 0.0, rtol=0, atol=0.01)


def test_a_part_far_below_the_plates_is_not_corrected(tmp_path):
    """Plates written in the part's frame (holes at Z -5) put the data 400 mm above the part: the
    ram stood at -5 and 95 mm (tools 100 and 200), the holes are cut with it at -412 and -312.
    Outside that region nothing is corrected; asked to extrapolate (every block, whatever its
    standard error), X and Y are, Z is not (the old fit: Z corrections at the 50 um bound, from a
    roll of X that nothing read)."""
    rows = _compensated(tmp_path, -5.0)
    assert not [r for r in rows if r["corrected"] == "1"], rows
    assert all("Z" in r["outside_support"] for r in rows if r["z_mm"]), rows
    rows = [r for r in _compensated(tmp_path, -5.0, "--extrapolate", "--max-correction-sd-um", "0")
            if r["corrected"] == "1"]
    assert len(rows) >= 8, rows
    np.testing.assert_allclose([float(r["cz_um"] or 0.0) for r in rows], 0.0, rtol=0, atol=0.01)


def test_predict_gives_no_depth_error(tmp_path):
    """predict at the plates' own holes, the truth's full deviation (dz of 16 um range there, from
    the squareness B0Z and A0Z the truth holds): dz is 0 (the old fit: up to 0.79 um, from the roll
    of X) with no standard error, since nothing read it; dx and dy have one."""
    machine, model = _model(tmp_path, ZDEPTH)
    pred = tmp_path / "pred.csv"
    assert main(["predict", str(machine), str(model), str(tmp_path / "full_0.csv"), "-o", str(pred)]) == 0
    with open(pred) as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 154 and np.ptp([float(r["dz_um"]) for r in rows]) > 10.0
    np.testing.assert_allclose([float(r["pred_dz_um"]) for r in rows], 0.0, rtol=0, atol=0.01)
    assert all(r["pred_dz_um_sd"] == "" and float(r["pred_dx_um_sd"]) > 0 for r in rows), rows[0]


def test_points_at_three_heights_keep_the_pitches_they_measure(tmp_path, capsys):
    """The rule holds only what the data leave open. Points at three heights (Z -417, -204, 9 mm)
    with tools of 100 and 200 mm read the table's pitch EBX (dx changes with the tip's height as
    EBX times it) and the saddle's pitch EAY (dy likewise): the fit keeps them, their range within
    3 standard errors of the truth's (30 urad over X's 762 mm, 20 urad over Y's 406 mm, over the
    travel the data reached), and does not report them held at zero."""
    machine = tmp_path / "m.toml"
    machine.write_text(MACHINE)
    truth = TruthMachine(str(machine))
    truth.components["X"]["EBX"] = P.Linear(0.0, 30e-6 / 762.0)
    truth.components["Y"]["EAY"] = P.Linear(0.0, -20e-6 / 406.0)
    rng = np.random.default_rng(6)
    files = [str(tc.points(truth, tmp_path / f"p{k}.csv", rng, grid=(11, 7, 3), margin=0.18,
                           tool_lengths_mm=(100.0, 200.0), directions=(1,), noise_um=1.0).path)
             for k in range(2)]
    assert main(["identify", str(machine), *files, "-o", str(tmp_path / "model.json")]) == 0
    text = capsys.readouterr().out
    for axis, comp, per_mm in (("X", "EBX", 30.0 / 762.0), ("Y", "EAY", 20.0 / 406.0)):
        lo, hi = map(float, re.search(rf"{axis} from (-?[\d.]+) to (-?[\d.]+) mm", text).groups())
        m = re.search(rf"{comp}\s+range\s+([\d.]+) \+- ([\d.]+) urad", text)
        assert m, text
        value, sd = float(m.group(1)), float(m.group(2))
        np.testing.assert_allclose(value, per_mm * (hi - lo), rtol=0, atol=3.0 * sd)
