"""A table whose data cover part of its axis's reach: beyond the data it corrects nothing.

An identifiability tester measured a C table over 0 .. 180 deg only. The LinuxCNC table stopped at
180 deg, and LinuxCNC holds a table's end values beyond it (src/emc/motion/command.c: the entries
at -DBL_MAX and +DBL_MAX take the first and last values), so C over 180 .. 360 deg got the 180 deg
trim, +30 urad, where the truth is 0 .. -30 urad from C 0: at 350 deg 29.8 urad left against 0.2
with no table, while compensate leaves those angles uncorrected.

The truth here is numpy, written down by hand: C's positioning error (actual minus commanded angle)
ECC(C) = 5 + 15 cos C urad. The model holds that profile (ECC_0 = 5, ECC_c1 = 15 urad) and says its
data reached C 0 .. 180 deg only. The tables are applied as the controllers apply them, by readers
that share no code with mtcomp.export (tests/test_export_formats.py): LinuxCNC adds the trim
interpolated linearly at the commanded joint position, holding the end values beyond the table;
Sinumerik's LEC holds the error at _MIN + N _STEP (a positive value moves the axis negative), its
end values beyond. The turn is swept over C's whole travel, -360 .. 360 deg.
"""
from __future__ import annotations

import csv

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from test_export_formats import read_linuxcnc_comp, read_siemens

URAD = 1e-6
R_MM = 100.0            # the tool tip's distance from C's line in the compensated program


def truth_ecc_urad(c_deg):
    """The hand-made rotary: C's positioning error, urad."""
    return 5.0 + 15.0 * np.cos(np.radians(c_deg))


@pytest.fixture(scope="module")
def half_turn(tmp_path_factory):
    """MODEL.json of ECC = 5 + 15 cos C urad whose data reached C 0 .. 180 deg (cbfxyz: C's travel
    -360 .. 360 deg)."""
    f = FittedModel.zero(ErrorModel(load_machine("cbfxyz"), ()))
    f.params.set_file_value("ECC_0", 5.0)
    f.params.set_file_value("ECC_c1", 15.0)
    f.support = {"C": (0.0, np.pi)}
    path = tmp_path_factory.mktemp("span") / "half_turn.json"
    save_model(path, f)
    return path


def left_after(c_deg, trim_urad):
    """(with the table, without) C's error left at the commanded angles ``c_deg``, urad, less its
    value at C 0 (the zero offset no table carries: the axis's home offset takes it)."""
    before = truth_ecc_urad(c_deg) - truth_ecc_urad(0.0)
    reached = c_deg + trim_urad * URAD * 180.0 / np.pi       # the command plus the trim
    return trim_urad + truth_ecc_urad(reached) - truth_ecc_urad(0.0), before


def test_a_half_turn_table_is_never_worse_than_none_anywhere_on_the_turn(half_turn, tmp_path, capsys):
    c = np.linspace(-360.0, 360.0, 14401)                     # every 0.05 deg
    lc = tmp_path / "lc"
    assert main(["export", "cbfxyz", str(half_turn), "--format", "linuxcnc", "-o", str(lc)]) == 0
    nom, fwd, rev = read_linuxcnc_comp(lc / "c.comp", 1)
    np.testing.assert_array_equal(fwd, rev)
    trim = np.interp(c, nom, fwd) * np.pi / 180.0 / URAD       # deg -> urad; ends held, as LinuxCNC
    sie = tmp_path / "sie"
    assert main(["export", "cbfxyz", str(half_turn), "--format", "siemens", "-o", str(sie)]) == 0
    pos, err = read_siemens((sie / "AX_EEC.INI").read_text())[0]["AX5"]
    lec = -np.interp(c, pos, err) * np.pi / 180.0 / URAD       # the LEC holds the error
    readme = (lc / "README.txt").read_text()
    capsys.readouterr()
    for name, t, grid in (("linuxcnc", trim, nom), ("siemens", lec, pos)):
        after, before = left_after(c, t)
        # nowhere worse than no table (the ramp beyond 180 deg included: there the truth, -30 urad,
        # is on the other side of the trim's)
        assert np.max(np.abs(after) - np.abs(before)) < 0.01, name
        span = (c >= 0.0) & (c <= 180.0)
        assert np.max(np.abs(after[span])) < 0.01, name          # the data's span: corrected
        # one grid step past the span's ends, and from there on, the table corrects nothing
        assert grid[0] < 0.0 and grid[-1] > 180.0 and grid[-1] - grid[-2] <= 2.0
        beyond = (c <= grid[0]) | (c >= grid[-1])
        np.testing.assert_array_equal(after[beyond], before[beyond])
        at350 = np.argmin(np.abs(c - 350.0))
        assert abs(after[at350]) == pytest.approx(0.23, abs=0.01), name   # main left 29.8 urad
    assert "the data reach 0 .. 180 deg" in readme and "ramps to zero" in readme


def test_the_table_is_compensates_correction_in_the_span_and_none_beyond(half_turn, tmp_path, capsys):
    """C turns a full turn with the tip 100 mm from its line (X 100, Y 0): compensate corrects the
    blocks at C 0 .. 180 deg and leaves the rest, as a turn away (360 deg) is the angle itself.
    Hand-derived: in the part's frame the tip is off along the circle's tangent (sin C, cos C) by
    -ECC(C) R; the table turns C by its trim t, which takes t R off that. Inside the span the two
    agree up to one constant (-ECC(0) R = -2 um, the zero offset no table carries), to 0.01 um; at
    every block compensate leaves uncorrected the table is zero."""
    prog = tmp_path / "c.nc"
    cs = np.arange(0, 361, 10)
    prog.write_text("G21 G90 G94\nG0 X100 Y0 Z50 B0 C0\n" + "".join(f"G1 C{c:g} F1000\n" for c in cs)
                    + "M30\n")
    rep = tmp_path / "b.csv"
    assert main(["compensate", "cbfxyz", str(half_turn), str(prog), "-o", str(tmp_path / "o.nc"),
                 "--report", str(rep)]) == 0
    rows = {int(r["line"]): r for r in csv.DictReader(open(rep, newline=""))}
    rows = [rows[3 + k] for k in range(cs.size)]
    assert [float(r["c_deg"]) for r in rows] == list(cs.astype(float))
    corrected = np.array([r["corrected"] == "1" for r in rows])
    np.testing.assert_array_equal(corrected, (cs <= 180) | (cs == 360))
    cy = np.array([float(r["cy_um"]) for r in rows])
    rad = np.radians(cs)
    tangent = np.array([float(r["ex_before_um"]) for r in rows]) * np.sin(rad) + \
        np.array([float(r["ey_before_um"]) for r in rows]) * np.cos(rad)
    np.testing.assert_allclose(tangent, -truth_ecc_urad(cs) * URAD * R_MM * 1e3, rtol=0, atol=1e-3)
    assert main(["export", "cbfxyz", str(half_turn), "--format", "linuxcnc", "-o", str(tmp_path / "lc")]) == 0
    capsys.readouterr()
    nom, fwd, _ = read_linuxcnc_comp(tmp_path / "lc" / "c.comp", 1)
    t_r = np.interp(cs, nom, fwd) * np.pi / 180.0 * R_MM * 1e3           # t R, um
    inside = cs <= 180
    diff = tangent[inside] - t_r[inside]
    assert np.ptp(diff) < 0.02 and diff.mean() == pytest.approx(-2.0, abs=0.01)
    assert np.ptp(t_r[inside]) > 2.0                     # a correction that changes along the span
    np.testing.assert_array_equal(cy[~corrected], 0.0)
    np.testing.assert_array_equal(t_r[~corrected], 0.0)
