"""The identify report says one thing of a profile the data determine and find flat.

An R-test campaign on a CBFXYZ machine (three balls on the table read at B and C poses, the
instrument's frame the workpiece's: ``--known-setup``) determines the angular positioning errors
EBB and ECC: on the independent truth machine (tests/truth) with ECC = 5 urad sin 2C the fit
finds its range, 10 urad, within its standard error. With no ECC in the truth, the roughness
penalty's weight (REML) goes to its bound and holds the harmonics at zero with no posterior
variance: the report once read that as "ECC range not determined by the data" (and "2 of these are
not determined by the data alone") while its last line said "every fitted parameter is determined
by the data". It says the range is 0, smoothed flat, and nothing of it undetermined."""
from __future__ import annotations

import re

import numpy as np

from mtcomp.cli import main
from truth import TruthMachine
from truth.profiles import Fourier

BALLS = [np.array([100.0, 0.0, 50.0]), np.array([0.0, 80.0, 150.0]), np.array([-70.0, -60.0, 20.0])]
POSES = ([(0, c) for c in range(0, 360, 30)] + [(b, 0) for b in range(-90, 91, 15)]
         + [(45, c) for c in range(0, 360, 45)] + [(-60, c) for c in range(0, 360, 60)])
LOCATION = {"X0C": 12e-3, "Y0C": -8e-3, "A0C": 20e-6, "Z0B": 15e-3}


def _rtest(path, ecc_sin2_rad: float, seed: int = 5, ecc_zero_rad: float = 0.0):
    """The R-test file of a truth machine with the location errors LOCATION and ECC = ecc0 + ecc
    sin 2C: each ball's commanded tip (its nominal place in the bed frame) and its deviation, 0.3 um
    noise."""
    m = TruthMachine.zero("cbfxyz")
    m.location.update(LOCATION)
    m.components["C"]["ECC"] = Fourier(ecc_zero_rad, (0.0, 0.0), (0.0, ecc_sin2_rad))
    rng = np.random.default_rng(seed)
    rows = ["x_mm,y_mm,z_mm,b_deg,c_deg,tool_mm,dx_um,dy_um,dz_um,run"]
    for p in BALLS:
        for b, c in POSES:
            q0 = m.q_from(b_deg=b, c_deg=c)[None, :]
            tip = (m.wp2bed(q0, errors=False) @ np.r_[p, 1.0])[0, :3]
            q = m.q_from(*tip, b_deg=b, c_deg=c)[None, :]
            d = m.true_deviation(q, tool_length=100.0)[0][0] * 1e3 + rng.normal(0.0, 0.3, 3)
            rows.append(f"{tip[0]:.4f},{tip[1]:.4f},{tip[2]:.4f},{b},{c},100,"
                        f"{d[0]:.4f},{d[1]:.4f},{d[2]:.4f},1")
    path.write_text("\n".join(rows) + "\n")
    return path


def _identify(tmp_path, capsys, ecc, ecc_zero=0.0):
    src = _rtest(tmp_path / f"rtest_{ecc:g}.csv", ecc, ecc_zero_rad=ecc_zero)
    assert main(["identify", "cbfxyz", str(src), "--hold", "X,Y,Z,squareness,spindle",
                 "--known-setup", str(src), "-o", str(tmp_path / "M.json")]) == 0
    return capsys.readouterr().out


def test_the_data_determine_the_rotary_positioning_error_they_find(tmp_path, capsys):
    out = _identify(tmp_path, capsys, 5e-6)
    m = re.search(r"ECC\s+range\s+([\d.]+) \+- ([\d.]+) urad", out)
    assert m, out
    value, sd = float(m.group(1)), float(m.group(2))
    assert abs(value - 10.0) <= 3.0 * sd and sd < 2.0, out
    assert "every fitted parameter is determined by the data" in out


def test_a_flat_profile_is_reported_flat_not_undetermined(tmp_path, capsys):
    out = _identify(tmp_path, capsys, 0.0)
    # one thing: no row "not determined by the data", no count of them, and the last line's verdict
    assert not re.findall(r"not determined by the data$", out, re.M), out
    assert "of these are not determined by the data alone" not in out
    assert "every fitted parameter is determined by the data" in out
    assert "hint:" not in out                        # held already: no hint
    for comp in ("EBB", "ECC"):
        assert re.search(rf"{comp}\s+range 0 urad \(the data show none above their noise: smoothed "
                         r"flat\)", out), out
    # the location errors the truth holds, within 4 standard errors
    for name, truth in (("X0C", 12.0), ("Y0C", -8.0), ("A0C", 20.0), ("Z0B", 15.0)):
        m = re.search(rf"{name}\s+(-?[\d.]+) \+- ([\d.]+) u", out)
        assert m and abs(float(m.group(1)) - truth) <= 4 * float(m.group(2)) + 0.05, (name, out)


def test_the_report_gives_a_rotary_axis_zero_offset(tmp_path, capsys):
    """A constant angular positioning error of C (its zero offset, 30 urad in the truth) has no range:
    the report gives it as ECC_0 with its standard error (a user's A zero offset of 40 urad showed
    only as "EAA range 0 urad ... smoothed flat")."""
    out = _identify(tmp_path, capsys, 0.0, ecc_zero=30e-6)
    m = re.search(r"zero offset of C\s+ECC_0\s+([-\d.]+) \+- ([\d.]+) urad", out)
    assert m, out
    value, sd = float(m.group(1)), float(m.group(2))
    assert abs(value - 30.0) <= 3.0 * sd and sd < 2.0, out


def test_an_r_test_without_hold_says_which_hold(tmp_path, capsys, monkeypatch):
    """The same R-test (fewer poses) without --hold: the linear axes move only with B and C, and
    combinations the data leave open trade the rotary axes' errors against theirs (the tool axis's
    tilts and B's zero against the tilts of Z, which no laser names). The turn about Z, ECC_0
    against the squareness C0Y and the slope of X's straightness in Y, goes by the convention (X the
    reference axis: EYX's slope zero): ECC_0 and C0Y are given with standard errors, at the truth's
    0 within 3 sd (before the convention held wherever the turn is open, ECC_0 was "not determined
    by the data"). The report, and the run's last notes, say which --hold (before: a column of "not
    determined by the data" and nothing on what to do)."""
    monkeypatch.setattr(__import__(__name__), "POSES", [(0, c) for c in range(0, 360, 45)]
                        + [(b, 0) for b in range(-90, 91, 30)] + [(45, c) for c in range(0, 360, 90)])
    src = _rtest(tmp_path / "rtest.csv", 5e-6)
    assert main(["identify", "cbfxyz", str(src), "--known-setup", str(src), "-o", str(tmp_path / "M.json")]) == 0
    out = capsys.readouterr().out
    for name in ("ECC_0", "C0Y"):
        m = re.search(rf"{name}\s+(-?[0-9.e+-]+) \+- ([0-9.e+-]+) urad", out)
        assert m, out
        value, sd = float(m.group(1)), float(m.group(2))
        assert abs(value) <= 3.0 * sd and sd < 2.0, (name, value, sd)
    assert re.search(r"A0S\s+not determined by the data", out), out
    hints = [line for line in out.splitlines() if "--hold X,Y,Z,squareness,spindle" in line]
    assert len(hints) == 2 and hints[0].startswith("  hint: ") and hints[1].startswith("note: "), out


def test_laser_runs_of_every_axis_get_no_hold_hint(tmp_path, capsys):
    """Laser runs of X, Y, Z, B and C determine the linear axes' components, whatever they leave open
    of the rotary axes' location: no --hold is suggested (a first rule, on open combinations alone,
    told this campaign to hold X, Y and Z)."""
    from truth import campaigns as tc
    rng = np.random.default_rng(5)
    m = TruthMachine.random("cbfxyz", rng, effects=[], error_motions=False)
    files = [str(tc.laser(m, tmp_path / f"{a}.csv", rng, a, n_runs=2).path) for a in "XYZBC"]
    assert main(["identify", "cbfxyz", *files, "-o", str(tmp_path / "M.json")]) == 0
    out = capsys.readouterr().out
    assert "of these are not determined by the data alone" in out and "hint:" not in out, out
