"""What an R-test's fitted frame takes from the table is not corrected; an extrapolated correction
claims no standard error.

A double turntable (CBFXYZ) whose rotary axes' lines are off (location offsets and tilts), whose
zero offsets are not zero and whose positioning errors vary with the angle, read by an R-test with
one ball on the table (B 0..90, C all round). Without ``--known-setup`` the ball's frame is fitted,
and its shift takes what the table's zero offset and its lines' location make alike at the ball;
elsewhere on the part they move the tip by up to 2.8 um, which no reading tells. Before, compensate
corrected every block of a program with standard errors of 0.09 um while the truth missed its
prediction by 2.3 um (26 of them). Now such blocks are left uncorrected and the summary names the
parameters; with ``--known-setup`` the same data correct the program.

Oracle: an independent truth in plain numpy (textbook homogeneous transforms, sharing no code with
mtcomp), the compensated positions taken from BLOCKS.csv and evaluated on it."""
import csv

import numpy as np
import pytest

from mtcomp.cli import main

UM, UR = 1e-3, 1e-6
PB, PC = np.array([0.0, 0.0, -100.0]), np.zeros(3)      # cbfxyz's B and C axis points (mm)
HOLD = ["--hold", "X,Y,Z,squareness,spindle"]


def _rot(u, th):
    u = np.asarray(u, float) / np.linalg.norm(u)
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    T = np.eye(4)
    T[:3, :3] = np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K
    return T


def _about(u, th, p):
    """A turn by ``th`` about the line along ``u`` through ``p``."""
    A, B = np.eye(4), np.eye(4)
    A[:3, 3], B[:3, 3] = p, -np.asarray(p, float)
    return A @ _rot(u, th) @ B


def _table(b, c, actual):
    """4x4: workpiece frame to machine frame at B, C (rad), nominal or with the truth's errors."""
    if not actual:
        return _about([0, 1, 0], b, PB) @ _about([0, 0, 1], c, PC)
    uB = _rot([0, 0, 1], 12 * UR)[:3, :3] @ _rot([1, 0, 0], 20 * UR)[:3, :3] @ [0, 1.0, 0]
    uC = _rot([0, 1, 0], -10 * UR)[:3, :3] @ _rot([1, 0, 0], 15 * UR)[:3, :3] @ [0, 0, 1.0]
    eb = (25.0 + 40.0 * np.sin(b) ** 2) * UR
    ec = (20.0 + 15.0 * np.cos(2 * c) + 10.0 * np.sin(3 * c)) * UR
    return (_about(uB, b + eb, PB + np.array([10.0, 0, -15.0]) * UM)
            @ _about(uC, c + ec, PC + np.array([12.0, -8.0, 0]) * UM))


def _tip(q, actual=True):
    """(3,) mm: the tool tip (X Y Z in the machine frame, perfect linear axes) in the workpiece
    frame at axis positions q = (x, y, z, b_deg, c_deg)."""
    M = _table(np.radians(q[3]), np.radians(q[4]), actual)
    return (np.linalg.inv(M) @ np.r_[q[:3], 1.0])[:3]


def _deviation_um(q):
    return (_tip(q) - _tip(q, False)) / UM


def _command(p, b, c):
    """X Y Z that put the nominal tip on workpiece point p at B, C (deg)."""
    return (_table(np.radians(b), np.radians(c), False) @ np.r_[p, 1.0])[:3]


def _rtest(path, balls, bs, cs, seed=1):
    rng = np.random.default_rng(seed)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["x_mm", "y_mm", "z_mm", "b_deg", "c_deg", "dx_um", "dy_um", "dz_um", "tool_mm"])
        for p in balls:
            for b in bs:
                for c in cs:
                    xyz = _command(np.array(p, float), b, c)
                    d = _deviation_um([*xyz, b, c]) + rng.normal(0.0, 0.2, 3)
                    w.writerow([*np.round(xyz, 4), b, c, *np.round(d, 4), 100.0])


def _program(path, poses):
    lines = ["G21 G90 G17 G94"]
    for n, (p, b, c) in enumerate(poses):
        x, y, z = _command(np.array(p, float), b, c)
        lines.append(f"N{10 * (n + 1)} G1 X{x:.4f} Y{y:.4f} Z{z:.4f} B{b:.4f} C{c:.4f} F1000")
    path.write_text("\n".join(lines + ["M30"]) + "\n")


def _blocks(tmp_path, model, poses, *extra):
    """(summary text, BLOCKS.csv rows with the truth's deviation after the correction, less the
    datum's (machine zero), um, as 'true_after')."""
    prog = tmp_path / "p.nc"
    _program(prog, poses)
    report = tmp_path / "b.csv"
    assert main(["compensate", "cbfxyz", str(model), str(prog), "-o", str(tmp_path / "c.nc"),
                 "--report", str(report), *extra]) == 0
    d0 = _deviation_um([0.0, 0.0, 0.0, 0.0, 0.0])
    rows = list(csv.DictReader(open(report)))
    for r in rows:
        q = np.array([float(r[k]) for k in ("x_mm", "y_mm", "z_mm", "b_deg", "c_deg")])
        dq = np.array([float(r["cx_um"]) * UM, float(r["cy_um"]) * UM, float(r["cz_um"]) * UM,
                       np.degrees(float(r["cb_urad"]) * UR), np.degrees(float(r["cc_urad"]) * UR)])
        r["true_after"] = (_tip(q + dq) - _tip(q, False)) / UM - d0
        r["true_before"] = _deviation_um(q) - d0
    return rows


POSES = [((x, y, 30.0), 0.0, c) for c in (0.0, 90.0) for x, y in ((-100, -100), (100, 100))] \
    + [((x, y, 30.0), 30.0, 180.0) for x, y in ((-100, -100), (100, 100))]


@pytest.fixture(scope="module")
def one_ball(tmp_path_factory):
    folder = tmp_path_factory.mktemp("one_ball")
    data = folder / "rtest.csv"
    _rtest(data, [(150.0, 0.0, 20.0)], (0, 30, 60, 90), range(0, 360, 30))
    return folder, data


def test_what_the_fitted_frame_takes_is_not_corrected(one_ball, tmp_path, capsys):
    folder, data = one_ball
    model = folder / "fitted.json"
    assert main(["identify", "cbfxyz", str(data), "-o", str(model), *HOLD]) == 0
    capsys.readouterr()
    rows = _blocks(tmp_path, model, POSES)
    out = capsys.readouterr().out
    # a corrected block's prediction after is within three of its standard errors of the truth
    # (before: 2.3 um off at 0.09 um); here none is corrected, and the summary names why
    for r in rows:
        if r["corrected"] == "1":
            pred = np.array([float(r[k]) for k in ("ex_after_um", "ey_after_um", "ez_after_um")])
            assert np.abs(r["true_after"] - pred).max() <= 3.0 * float(r["correction_sd_um"]), r
    assert all(r["corrected"] == "0" and r["correction_sd_um"] == "" for r in rows), rows
    assert "ECC_0" in out and "X0C" in out and "--known-setup" in out, out


def test_a_known_frame_corrects_the_same_program(one_ball, tmp_path):
    folder, data = one_ball
    model = folder / "known.json"
    assert main(["identify", "cbfxyz", str(data), "-o", str(model), *HOLD,
                 "--known-setup", str(data)]) == 0
    rows = _blocks(tmp_path, model, POSES)
    assert all(r["corrected"] == "1" for r in rows), rows
    before = np.sqrt(np.mean([np.sum(r["true_before"] ** 2) for r in rows]))
    after = np.sqrt(np.mean([np.sum(r["true_after"] ** 2) for r in rows]))
    assert before > 15.0 and after < 1.5, (before, after)


def test_an_extrapolated_correction_claims_no_standard_error(tmp_path, capsys):
    data = tmp_path / "rtest.csv"
    _rtest(data, [(150.0, 0.0, 20.0), (0.0, 150.0, 120.0)], (0, 15, 30, 45), range(0, 360, 30))
    model = tmp_path / "m.json"
    assert main(["identify", "cbfxyz", str(data), "-o", str(model), *HOLD,
                 "--known-setup", str(data)]) == 0
    capsys.readouterr()
    poses = [((x, y, 30.0), 90.0, c) for c in (0.0, 90.0) for x, y in ((-100, -100), (100, 100))]
    rows = _blocks(tmp_path, model, poses, "--extrapolate")
    out = capsys.readouterr().out
    # B at 90 deg, the data's B 0..45: corrected as asked, with the model's continuation, which
    # misses the truth by several um: no standard error claims it (before: 0.19 um)
    assert all(r["outside_support"] == "B" and r["corrected"] == "1" for r in rows), rows
    assert all(r["correction_sd_um"] == "" for r in rows), rows
    assert "no standard error sizes" in out, out
