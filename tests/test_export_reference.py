"""`mtcomp export` places every table in machine coordinates, numbered from the machine's reference
position, also when the data do not start at 0.

The model is built by hand: on the polynomial basis ``EXX(x) = EXX_1 (x / 1 m)``, so EXX_1 = 1000 um
is an error of exactly x um at X = x mm (1 um per mm), and EYX_1 = 500 um a straightness of 0.5 um
per mm. The data reach X = 15 .. 55.8 mm. Beyond the data the model is not used: the tables hold
the value at the data's nearest end. So, relative to the reference position 0 (the machine zero),
the error is ``E(s) = max(s, 15) - 15`` um (up to 55.8), the correction minus that. A Fanuc places
point n at ``reference position + (n - 3620) * 3624`` (FANUC Series 0i-PB parameter manual,
B-63980EN/01, parameters 3620-3624): the replay below puts the reference position at machine
coordinate 0, as the controller does.
"""
import csv

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import Backlash, ErrorModel, FittedModel, deviation, save_model
from mtcomp.models.params import ParameterSet
from test_export_formats import parse_fanuc_tape, read_fanuc, read_heidenhain_table, read_isg, read_isg_ssfk, read_klipper, \
    read_linuxcnc_comp, read_siemens

LO, HI = 15.0, 55.8
UM = 1e-3   # mm


def linear_model(tmp_path, support=None, backlash_um=None, eyx_1=0.0, name="m.json"):
    """MODEL.json of EXX = x um (x in mm), EYX = eyx_1 / 1000 * x um, optionally a backlash on X."""
    terms = (Backlash("X"),) if backlash_um is not None else ()
    model = ErrorModel(load_machine("xfyz").with_basis("polynomial"), terms)
    ps = ParameterSet(model.param_specs)
    ps.set_file_value("EXX_1", 1000.0)
    if eyx_1:
        ps.set_file_value("EYX_1", eyx_1)
    if backlash_um is not None:
        ps.set_file_value("BL_X", backlash_um)
    fitted = FittedModel(model, ps, support=dict(support or {"X": (LO, HI)}))
    path = tmp_path / name
    save_model(path, fitted)
    return path, fitted


def export(path, out, fmt, *extra, machine="xfyz"):
    assert main(["export", machine, str(path), "--format", fmt, "-o", str(out), *extra]) == 0
    return out


def held_error_um(s, hi=HI):
    """The hand-derived error of X relative to the reference position 0 (um) at a table's points
    ``s``: EXX = x um inside the data (15 .. ``hi``), held at the data's ends, and zero past the
    table's first point beyond each end (there it has ramped to zero over one step: no table
    corrects where the data did not reach, as compensate corrects nothing there)."""
    s = np.asarray(s, dtype=float)
    first, last = s[s <= LO + 1e-9].max(initial=s[0]), s[s >= hi - 1e-9].min(initial=s[-1])
    return np.where((s < first - 1e-9) | (s > last + 1e-9), 0.0, np.clip(s, LO, hi) - LO)


# ------------------------------------------------------------------------------------ Fanuc
def test_fanuc_point_3620_is_the_machine_zero_and_the_table_reaches_the_data(tmp_path, capsys):
    path, _ = linear_model(tmp_path)
    out = export(path, tmp_path / "fa", "fanuc")
    err = capsys.readouterr().err
    text = (out / "pitch_error.txt").read_text()
    par = {n: v for (n, a), v in parse_fanuc_tape(text)[0].items() if a == 1}
    tables = read_fanuc(text, 1e-3)
    pos, comp = tables[1]["+"]
    # point 3620's position is the machine zero; the grid runs from it past the data's start
    assert pos[par[3620] - par[3621]] == 0.0
    assert pos[0] == pytest.approx(0.0, abs=1e-12) and (pos[-2], pos[-1]) == (56.0, 57.0)
    assert par[3624] == 1000 and len(pos) <= 128
    # the value at s, summed from the reference point: the correction at s minus that at the
    # reference, the data's end value held from 0 to 15 mm (1 unit = 1 um, cumulative rounding)
    np.testing.assert_allclose(comp, -held_error_um(pos) * UM, rtol=0, atol=0.5e-3 + 1e-12)
    at = {float(p): c for p, c in zip(pos, comp)}
    assert at[15.0] == pytest.approx(0.0, abs=1e-12)
    assert at[35.0] == pytest.approx(-20 * UM, abs=0.5e-3)     # old numbering gave -35 um here
    # pitch_points.csv lists the true positions and says which points are held
    rows = list(csv.DictReader(open(out / "pitch_points.csv", newline="")))
    np.testing.assert_allclose([float(r["position_mm"]) for r in rows], pos, rtol=0, atol=1e-9)
    np.testing.assert_array_equal([int(r["held"]) for r in rows], ((pos < LO) | (pos > HI)).astype(int))
    assert ("points 0 .. 14 (0 .. 14 mm) carry no compensation; point 56 (56 mm) holds the "
            "compensation at its value at 55.8 mm, the data's nearest end; point 57 (57 mm) carries no "
            "compensation: nothing was measured there, where compensate corrects nothing") in err
    assert "reference position 0 mm" in (out / "README.txt").read_text()


def test_fanuc_bidirectional_table_from_the_reference_follows_the_model(tmp_path):
    """With a backlash: the table for negative travel, 3626 and 3627, against the model's own
    prediction (mtcomp.models.deviation, second formulation) at the data's nearest end."""
    path, fitted = linear_model(tmp_path, backlash_um=-8.0)
    out = export(path, tmp_path / "fa", "fanuc")
    tables = read_fanuc((out / "pitch_error.txt").read_text(), 1e-3)
    m = fitted.machine

    def error(s, d):
        q = np.zeros((len(s), m.n_axes))
        q[:, 0] = np.clip(s, LO, HI)
        c = fitted.context(len(s), {"dir_X": np.full(len(s), d)})
        return deviation(fitted.model, q, fitted.params.values, c)[:, 0]

    for travel, d in (("+", 1.0), ("-", -1.0)):
        pos, comp = tables[1][travel]
        assert pos[0] == 0.0
        # each table is zero at the data's nearest end to the reference (the mean of both
        # directions there) and beyond the data (the reference point included): no correction
        zero = 0.5 * (error(np.array([LO]), 1.0)[0] + error(np.array([LO]), -1.0)[0])
        expected = np.where((pos < LO) | (pos > HI + 1.0), 0.0, -(error(pos, d) - zero))
        np.testing.assert_allclose(comp, expected, rtol=0, atol=0.5e-3 + 1e-12)
    # no reversal at the reference point: the data start at 15 mm, and below them no table corrects
    # (compensate corrects nothing there); from 15 mm on the two tables differ by the 8 um reversal
    pos, comp = tables[1]["-"]
    k = list(pos).index(15.0)
    assert comp[0] == 0.0 and comp[k] - tables[1]["+"][1][k] == pytest.approx(-8 * UM, abs=0.5e-3)
    # the README says what the files hold there: the + table zero, the - table the reversal (3627);
    # it said "the mean of the two approach directions", which the generic tables are, not these
    readme = " ".join((out / "README.txt").read_text().split())
    assert "mean of the two approach directions" not in readme
    assert ("where the model has a backlash, the table for positive travel; the table for negative "
            "travel (bidirectional, 3605#0 = 1) differs from it there by the reversal, which parameter "
            "3627 holds") in readme
    assert tables[1]["+"][1][0] == 0.0


def test_fanuc_reference_outside_the_travel_is_the_travels_nearest_end(tmp_path, capsys):
    """A machine whose X travel is 100 .. 800 mm: its zero cannot be reached, the reference position
    is taken at 100 mm, and the table runs from there (a note says so)."""
    mill = tmp_path / "mill.toml"
    mill.write_text('name = "carver800t-like"\ntopology = "XFYZ"\ntool_length_mm = 100.0\n'
                    "[axes.X]\ntravel_mm = [100.0, 800.0]\n[axes.Y]\ntravel_mm = [-300.0, 300.0]\n"
                    "[axes.Z]\ntravel_mm = [-250.0, 150.0]\n")
    path, _ = linear_model(tmp_path, support={"X": (150.0, 300.0)})
    out = export(path, tmp_path / "fa", "fanuc", machine=str(mill))
    err = capsys.readouterr().err
    assert ("axis X: the machine zero lies outside its travel 100:800 mm: its reference position is "
            "taken at the travel's nearest end, 100 mm") in err
    rows = list(csv.DictReader(open(out / "pitch_points.csv", newline="")))
    text = (out / "pitch_error.txt").read_text()
    p3620 = parse_fanuc_tape(text)[0][(3620, 1)]
    by_point = {int(r["point"]): r for r in rows}
    assert float(by_point[p3620]["position_mm"]) == 100.0
    pos = np.array([float(r["position_mm"]) for r in rows])
    comp = np.array([float(r["compensation_um"]) for r in rows])
    expected = np.where(pos > 300.0, 0.0, np.clip(pos, 150.0, 300.0) - 150.0)    # one step beyond: 0
    assert pos[-1] > 300.0 and comp[-1] == 0.0
    np.testing.assert_allclose(comp, -expected, rtol=0, atol=1e-3)


def test_fanuc_grid_step_grows_to_reach_a_far_region(tmp_path):
    """Data at 300 .. 390 mm: from the reference 0 the table needs 390 mm at most 128 points: the
    step grows to 5 mm (the smallest of 1, 2, 2.5, 5 x 10^k not below 390 / 127)."""
    path, _ = linear_model(tmp_path, support={"X": (300.0, 390.0)})
    out = export(path, tmp_path / "fa", "fanuc")
    pos, comp = read_fanuc((out / "pitch_error.txt").read_text(), 1e-3)[1]["+"]
    assert len(pos) <= 128 and pos[0] == 0.0 and (pos[-2], pos[-1]) == (390.0, 395.0)
    np.testing.assert_allclose(np.diff(pos), 5.0, rtol=0, atol=1e-9)
    expected = np.where(pos > 390.0, 0.0, np.clip(pos, 300.0, 390.0) - 300.0)
    np.testing.assert_allclose(comp, -expected * UM, rtol=0, atol=0.5e-3)


# ------------------------------------------------------------------------------------ every format
def test_every_format_states_machine_coordinates_for_data_not_starting_at_0(tmp_path):
    """Each format's positions, read as its controller reads them, are machine coordinates: the
    value found at machine X = s is the hand-derived error at s; each README names the reference
    position 0 mm (the old one said 15 mm)."""
    path, _ = linear_model(tmp_path, eyx_1=500.0)
    lc = export(path, tmp_path / "lc", "linuxcnc")
    nom, fwd, rev = read_linuxcnc_comp(lc / "x.comp", 1)
    assert (nom[0], nom[1], nom[-2], nom[-1]) == (LO - 1, LO, HI, HI + 1)
    np.testing.assert_allclose(fwd, -held_error_um(nom) * UM, rtol=0, atol=6e-7)
    np.testing.assert_allclose(rev, fwd, rtol=0, atol=0)

    sie = export(path, tmp_path / "sie", "siemens")
    lec, cec = read_siemens((sie / "AX_EEC.INI").read_text() + (sie / "NC_CEC.INI").read_text())
    pos, vals = lec["AX1"]
    assert pos[1] == LO
    np.testing.assert_allclose(vals, held_error_um(pos) * UM, rtol=0, atol=6e-7)   # the error itself
    eyx = [t for t in cec if t["input"] == "AX1" and t["output"] == "AX2"][0]
    assert eyx["positions"][1] == LO
    np.testing.assert_allclose(eyx["values"], -0.5 * held_error_um(eyx["positions"]) * UM, rtol=0,
                               atol=6e-7)

    hh = export(path, tmp_path / "hh", "heidenhain")
    cols, rows = read_heidenhain_table(hh / "X.COM")
    pos = np.array([float(r["AXISPOS"]) for r in rows])
    assert (pos[1], pos[-2]) == (LO, HI)
    np.testing.assert_allclose([float(r["X"]) for r in rows], -held_error_um(pos) * UM, rtol=0, atol=6e-6)
    np.testing.assert_allclose([float(r["Y"]) for r in rows], -0.5 * held_error_um(pos) * UM, rtol=0,
                               atol=6e-6)

    isg = export(path, tmp_path / "isg", "isg")
    _, vc = read_isg(isg / "vc_x.csv")
    assert (vc[1, 0], vc[-2, 0]) == (LO, HI)
    np.testing.assert_allclose(vc[:, 1], held_error_um(vc[:, 0]) * UM, rtol=0, atol=1e-12)
    np.testing.assert_allclose(vc[:, 2], 0.5 * held_error_um(vc[:, 0]) * UM, rtol=0, atol=1e-12)
    assert "// mean of both approach directions; reference position 0" in (isg / "vc_x.csv").read_text()
    pos, up, _ = read_isg_ssfk(isg / "achskw_x.lis")
    assert pos[1] == LO
    np.testing.assert_allclose(up, held_error_um(pos) * UM, rtol=0, atol=5.1e-5)

    # Klipper carries only the slope (0.5 um/mm of dy as X moves; Y has no table): no position
    kl = export(path, tmp_path / "skew.cfg", "klipper")
    assert read_klipper(kl)["xy_skew"] == pytest.approx(0.5e-3, rel=1e-6, abs=0)
    for readme in (lc, sie, hh, isg):
        assert "  X: 14 .. 5" in (readme / "README.txt").read_text()
    for text in [(d / "README.txt").read_text() for d in (lc, sie, hh, isg)] + [kl.read_text()]:
        assert "reference position 0 mm" in text and "reference position 15" not in text


# ------------------------------------------------------------------------------------ --range
def test_range_beyond_the_data_is_named_and_fanuc_still_starts_at_the_reference(tmp_path, capsys):
    path, _ = linear_model(tmp_path)
    lc = export(path, tmp_path / "lc", "linuxcnc", "--range", "X=-30:30")
    err = capsys.readouterr().err
    assert ("axis X: --range -30:30 mm reaches beyond the region of the data 15:55.8 mm: the table "
            "covers 15:30 mm") in err
    nom = read_linuxcnc_comp(lc / "x.comp", 1)[0]
    assert (nom[1], nom[-2]) == (LO, 30.0)
    fa = export(path, tmp_path / "fa", "fanuc", "--range", "X=-30:30")
    pos, comp = read_fanuc((fa / "pitch_error.txt").read_text(), 1e-3)[1]["+"]
    assert (pos[0], pos[-2]) == (0.0, 30.0)
    np.testing.assert_allclose(comp, -held_error_um(pos, 30.0) * UM, rtol=0, atol=0.5e-3)
    # a range inside the data is no clip of the data: nothing said
    capsys.readouterr()
    export(path, tmp_path / "lc2", "linuxcnc", "--range", "X=20:30")
    assert "reaches beyond" not in capsys.readouterr().err


# ------------------------------------------------------------------------------------ matrixkins
def test_matrixkins_writes_zero_unsigned_and_names_what_nothing_measured(tmp_path, capsys):
    """X alone measured, its EYX held at zero (no data): C_yx and C_zx are 0 with a comment that
    they were not measured (the old file wrote -0.000000000 without a word); a measured EYX of
    0.5 um/mm gives C_yx = -0.0005 and no such comment."""
    path, _ = linear_model(tmp_path)
    hal = (export(path, tmp_path / "lc", "linuxcnc") / "matrixkins.hal").read_text()
    err = capsys.readouterr().err
    assert "-0.000000000" not in hal
    lines = hal.splitlines()
    for name, comp in (("C_yx", "EYX"), ("C_zx", "EZX")):
        i = lines.index(f"setp matrixkins.{name} 0.000000000")
        assert lines[i - 1].startswith(f"# {name}: not measured") and comp in lines[i - 1]
    assert "C_xy, C_zy, C_xz, C_yz: not written: not measured" in hal
    assert "matrixkins.hal: not measured: C_yx, C_zx written as 0" in err
    path, _ = linear_model(tmp_path, eyx_1=500.0, name="m2.json")
    hal = (export(path, tmp_path / "lc2", "linuxcnc") / "matrixkins.hal").read_text()
    assert "setp matrixkins.C_yx -0.000500000" in hal and "# C_yx" not in hal
