"""`mtcomp export`: every format read back by a reader written here from the format's documentation.

The oracle is the model's own prediction, computed here with :func:`mtcomp.models.deviation` at the
grid positions the file names: the component error of axis L at s, approached in direction dir, is
``dev(P with q_L = s, dir_L = dir) - dev(P with q_L = 0)``, P the table pose (each other axis at
the middle of its data; docs/export.md). The readers below do not use
mtcomp.export:

* LinuxCNC: what usrmotLoadComp (src/emc/motion/usrmotintf.cc) does: three numbers per line, stop at
  the first line that is not; type 0 trim = nominal - column, type 1 trim = column.
* Siemens: ``$AA_ENC_COMP[0,N,AXk]`` at ``_MIN + N _STEP``; ``$AN_CEC[t,N]`` with its input / output
  axis and direction.
* Heidenhain: BEGIN line, header of column names, rows, [END]; value + BACKLASH moving negative.
* Fanuc: a parameter tape as the FANUC 30i parameter manual (B-63950EN/02, section 3.3) gives it,
  every line checked: ``%``, parameter blocks ``N03620Q1A1P35A2P121``, pitch error data
  ``N10001Q0P-1`` and ``%``, nothing else; 3620 .. 3627 and incremental pitch data N(10000 +
  point): the compensation at point n is the sum of the values from the reference point to n.
* ISG: ``//`` comments, a header of names, comma-separated rows.
* Klipper: the INI section ``[skew_correction mtcomp]``; checked against slopes fitted here with
  numpy.polyfit.
"""
import re
from pathlib import Path

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import Backlash, ErrorModel, FittedModel, PeriodicError, deviation, save_model
from mtcomp.models.params import ParameterSet

SUPPORT = {"X": (-100.0, 200.0), "Y": (-50.0, 80.0), "Z": (-60.0, 0.0)}
AXES = "XYZ"


def random_model(machine: str, terms, seed: int, sd: float, support) -> FittedModel:
    """A FittedModel whose every parameter is drawn from N(0, sd) in file units (um, urad)."""
    model = ErrorModel(load_machine(machine).with_basis("polynomial"), tuple(terms))
    ps = ParameterSet(model.param_specs)
    rng = np.random.default_rng(seed)
    for s in model.param_specs:
        ps.set_file_value(s.name, rng.normal(0.0, sd))
    return FittedModel(model, ps, support=support)


@pytest.fixture(scope="module")
def fitted():
    fm = random_model("xfyz", (Backlash("X"), PeriodicError("Y", 25.0)), 14, 40.0, dict(SUPPORT))
    fm.params.set_file_value("BL_X", -12.0)
    return fm


@pytest.fixture(scope="module")
def model_path(fitted, tmp_path_factory):
    p = tmp_path_factory.mktemp("model") / "model.json"
    save_model(p, fitted)
    return p


def beyond_the_ramp(positions, lo, hi):
    """(n,) bool: the points of a table past its first point at or beyond each end of the data's
    span lo .. hi, where the table is zero (docs/export.md, 'Where': it ramps to zero over the one
    grid step after that point)."""
    p = np.asarray(positions, dtype=float)
    first = p[p <= lo + 1e-9].max(initial=p[0])
    last = p[p >= hi - 1e-9].min(initial=p[-1])
    return (p < first - 1e-9) | (p > last + 1e-9)


def predicted(fitted, axis, positions, direction=0.0, tool_length=None, table=True):
    """(n, 3) tip deviation (mm) when only ``axis`` moves, the others at the table pose (each at the
    middle of its data, 0 without data: docs/export.md, 'The table pose'), minus the one with
    ``axis`` at its reference position (0); a position beyond the data at the data's nearest end,
    and, for the points of a table (``table``), zero past its first point beyond each end
    (:func:`beyond_the_ramp`)."""
    m = fitted.machine
    support = fitted.support or {}
    pose = [0.5 * sum(support[a]) if a in support else 0.0 for a in m.axis_names]
    positions = np.asarray(positions, dtype=float)
    lo, hi = support.get(axis, (-np.inf, np.inf))
    q = np.tile(pose, (len(positions), 1))
    q[:, m.index(axis)] = np.clip(positions, lo, hi)
    q0 = np.array([pose])
    q0[0, m.index(axis)] = 0.0
    cols = {f"dir_{axis}": np.full(len(positions), float(direction))}
    if tool_length is not None:
        cols["tool_length"] = np.full(len(positions), tool_length)
    c = fitted.context(len(positions), cols)
    c0 = fitted.context(1, None if tool_length is None else {"tool_length": np.array([tool_length])})
    d = deviation(fitted.model, q, fitted.params.values, c)[:, :3]
    d0 = deviation(fitted.model, q0, fitted.params.values, c0)[:, :3]
    out = d - d0
    if table and len(positions) > 1:
        out[beyond_the_ramp(positions, lo, hi)] = 0.0
    return out


def export(model_path, out, fmt, *extra):
    rc = main(["export", "xfyz", str(model_path), "--format", fmt, "-o", str(out), *extra])
    assert rc == 0
    return out


# ------------------------------------------------------------------------------------ LinuxCNC
def read_linuxcnc_comp(path, comp_type):
    """(nominal, forward trim, reverse trim), as LinuxCNC's loader reads a COMP_FILE."""
    nom, fwd, rev = [], [], []
    for line in Path(path).read_text().splitlines():
        parts = line.split()
        try:
            vals = [float(v) for v in parts[:3]]
        except ValueError:
            break
        if len(vals) != 3:
            break
        n, f, r = vals
        nom.append(n)
        fwd.append(f if comp_type == 1 else n - f)
        rev.append(r if comp_type == 1 else n - r)
    return np.array(nom), np.array(fwd), np.array(rev)


@pytest.mark.parametrize("comp_type", [1, 0])
def test_linuxcnc_comp_files_reproduce_the_model_with_backlash(fitted, model_path, tmp_path, comp_type):
    out = export(model_path, tmp_path / "lc", "linuxcnc", "--comp-type", str(comp_type))
    for axis in AXES:
        text = (out / f"{axis.lower()}.comp").read_text()
        nom, fwd, rev = read_linuxcnc_comp(out / f"{axis.lower()}.comp", comp_type)
        assert len(nom) == len(text.splitlines()), "every line must be read: no header, no comment"
        assert 2 <= len(nom) <= 256
        assert np.all(np.diff(nom) > 0)
        lo, hi = SUPPORT[axis]
        # the data's span, then one grid step beyond each end (inside the travel) with no correction
        assert nom[1] == pytest.approx(lo, abs=1e-9) and nom[-2] == pytest.approx(hi, abs=1e-9)
        assert nom[1] - nom[0] == pytest.approx(nom[2] - nom[1], abs=1e-9)
        assert nom[-1] - nom[-2] == pytest.approx(nom[2] - nom[1], abs=1e-9)
        for col in (fwd, rev):
            assert col[0] == 0.0 and col[-1] == 0.0
        j = AXES.index(axis)
        e_f = predicted(fitted, axis, nom, +1.0)[:, j]
        e_r = predicted(fitted, axis, nom, -1.0)[:, j]
        # the trim added to the command is minus the error; 6 decimals of mm
        np.testing.assert_allclose(fwd, -e_f, rtol=0, atol=6e-7)
        np.testing.assert_allclose(rev, -e_r, rtol=0, atol=6e-7)
        if axis == "X":
            assert np.median(rev - fwd) == pytest.approx(-12e-3, abs=1e-6)   # BL = up - down
    ini = (out / "ini_lines.txt").read_text()
    assert "[JOINT_0]" in ini and "COMP_FILE = x.comp" in ini and f"COMP_FILE_TYPE = {comp_type}" in ini


def test_linuxcnc_matrixkins_is_identity_minus_the_fitted_slopes(fitted, model_path, tmp_path):
    out = export(model_path, tmp_path / "lc", "linuxcnc")
    setp = dict(re.findall(r"setp matrixkins\.(C_\w\w) (\S+)", (out / "matrixkins.hal").read_text()))
    for i in AXES:
        for j in AXES:
            if i == j:
                continue
            lo, hi = SUPPORT[j]
            s = np.linspace(lo, hi, 7)
            slope = np.polyfit(s, predicted(fitted, j, s)[:, AXES.index(i)], 1)[0]
            # joint = C . axis: C = I - S with S the slope of the deviation along i as j moves
            assert float(setp[f"C_{i.lower()}{j.lower()}"]) == pytest.approx(-slope, rel=0.05, abs=1e-8)


def test_linuxcnc_default_grid_fits_256_points_over_a_long_axis(fitted, tmp_path):
    fm = FittedModel(fitted.model, fitted.params, support={"X": (-400.0, 400.0)})
    p = tmp_path / "m.json"
    save_model(p, fm)
    out = export(p, tmp_path / "lc", "linuxcnc")
    nom, _, _ = read_linuxcnc_comp(out / "x.comp", 1)
    assert len(nom) <= 256 and nom[0] == -400 and nom[-1] == 400
    assert not (out / "y.comp").exists()


# ------------------------------------------------------------------------------------ Siemens
def read_siemens(text):
    """LEC: axis -> (positions, values); CEC: list of dicts (input, output, direction, positions,
    values), from the INI assignments."""
    assign = dict(re.findall(r"^(\$\w+\[[^\]]*\])=(\S+)$", text, flags=re.M))
    lec, cec = {}, []
    axes = sorted({k.split(",")[-1].rstrip("]") for k in assign if k.startswith("$AA_ENC_COMP[")})
    for ax in axes:
        n = len([k for k in assign if re.match(rf"\$AA_ENC_COMP\[0,\d+,{ax}\]", k)])
        vals = np.array([float(assign[f"$AA_ENC_COMP[0,{i},{ax}]"]) for i in range(n)])
        lo, step = float(assign[f"$AA_ENC_COMP_MIN[0,{ax}]"]), float(assign[f"$AA_ENC_COMP_STEP[0,{ax}]"])
        assert float(assign[f"$AA_ENC_COMP_MAX[0,{ax}]"]) == pytest.approx(lo + (n - 1) * step, abs=1e-6)
        lec[ax] = (lo + step * np.arange(n), vals)
    t = 0
    while f"$AN_CEC_INPUT_AXIS[{t}]" in assign:
        n = len([k for k in assign if re.match(rf"\$AN_CEC\[{t},\d+\]", k)])
        lo, step = float(assign[f"$AN_CEC_MIN[{t}]"]), float(assign[f"$AN_CEC_STEP[{t}]"])
        cec.append({"input": assign[f"$AN_CEC_INPUT_AXIS[{t}]"].strip("()"),
                    "output": assign[f"$AN_CEC_OUTPUT_AXIS[{t}]"].strip("()"),
                    "direction": int(assign[f"$AN_CEC_DIRECTION[{t}]"]),
                    "positions": lo + step * np.arange(n),
                    "values": np.array([float(assign[f"$AN_CEC[{t},{i}]"]) for i in range(n)])})
        t += 1
    return lec, cec


def test_siemens_lec_and_cec_tables_reproduce_the_model(fitted, model_path, tmp_path):
    out = export(model_path, tmp_path / "sie", "siemens")
    lec_text = (out / "AX_EEC.INI").read_text()
    cec_text = (out / "NC_CEC.INI").read_text()
    assert lec_text.splitlines()[0] == "%_N_AX_EEC_INI" and lec_text.splitlines()[-1] == "M17"
    assert cec_text.splitlines()[0] == "%_N_NC_CEC_INI" and cec_text.splitlines()[-1] == "M17"
    lec, cec = read_siemens(lec_text + cec_text)
    ax_of = {f"AX{k + 1}": a for k, a in enumerate(AXES)}
    assert set(lec) == {"AX1", "AX2", "AX3"}
    for ax, (pos, vals) in lec.items():
        a = ax_of[ax]
        # from the data's low end, a point at or past the high end, and one step beyond each (zero)
        step = pos[1] - pos[0]
        assert len(pos) <= 125 and pos[1] == pytest.approx(SUPPORT[a][0], abs=1e-9)
        assert SUPPORT[a][1] - 1e-9 <= pos[-2] < SUPPORT[a][1] + step
        mean = 0.5 * (predicted(fitted, a, pos, 1.0) + predicted(fitted, a, pos, -1.0))
        # LEC holds the error itself (a positive value moves the axis negative)
        np.testing.assert_allclose(vals, mean[:, AXES.index(a)], rtol=0, atol=6e-7)
    own = [t for t in cec if t["input"] == t["output"]]
    assert sorted((ax_of[t["input"]], t["direction"]) for t in own) == [("X", -1), ("X", 1)]
    for t in own:
        pos = t["positions"]
        e = predicted(fitted, "X", pos, t["direction"])[:, 0]
        mean = 0.5 * (predicted(fitted, "X", pos, 1.0) + predicted(fitted, "X", pos, -1.0))[:, 0]
        # LEC (mean) + the correction of the directional table: the error moving that way, corrected
        np.testing.assert_allclose(mean - t["values"], mean + (e - mean), rtol=0, atol=2e-6)
        np.testing.assert_allclose(t["values"], -(e - mean), rtol=0, atol=6e-7)
    cross = [t for t in cec if t["input"] != t["output"]]
    assert len(cross) == 6 and all(t["direction"] == 0 for t in cross)
    for t in cross:
        a, d = ax_of[t["input"]], ax_of[t["output"]]
        e = 0.5 * (predicted(fitted, a, t["positions"], 1.0) + predicted(fitted, a, t["positions"], -1.0))
        np.testing.assert_allclose(t["values"], -e[:, AXES.index(d)], rtol=0, atol=6e-7)


def test_siemens_sign_flag_writes_the_error(fitted, model_path, tmp_path):
    out = export(model_path, tmp_path / "sie", "siemens", "--sign", "error")
    _, cec = read_siemens((out / "NC_CEC.INI").read_text())
    t = [t for t in cec if t["input"] == "AX1" and t["output"] == "AX2"][0]
    e = 0.5 * (predicted(fitted, "X", t["positions"], 1.0) + predicted(fitted, "X", t["positions"], -1.0))
    np.testing.assert_allclose(t["values"], e[:, 1], rtol=0, atol=6e-7)
    assert "NOT PUBLIC" in (out / "README.txt").read_text()


# ------------------------------------------------------------------------------------ Heidenhain
def read_heidenhain_table(path):
    lines = Path(path).read_text().splitlines()
    assert lines[0].startswith("BEGIN ") and lines[-1] == "[END]"
    cols = lines[1].split()
    rows = [dict(zip(cols, line.split())) for line in lines[2:-1]]
    return cols, rows


def test_heidenhain_com_tables_reproduce_the_model_with_backlash(fitted, model_path, tmp_path):
    out = export(model_path, tmp_path / "hh", "heidenhain")
    cma = (out / "AXIS.CMA").read_text().splitlines()
    head = cma[1].split()
    active = [line.split() for line in cma[2:-1] if line.split()[1:2] == ["*"]]
    assert len(active) == 1
    assigned = dict(zip(head, active[0]))
    for a in AXES:
        # [axis in a column of the .COM] = F(axis of the .CMA column the .COM is entered in)
        cols, rows = read_heidenhain_table(out / assigned[a])
        assert cols[:2] == ["NR", "AXISPOS"] and set(AXES) <= set(cols)
        assert len(rows) <= 256
        pos = np.array([float(r["AXISPOS"]) for r in rows])
        e_f, e_r = predicted(fitted, a, pos, 1.0), predicted(fitted, a, pos, -1.0)
        mean = 0.5 * (e_f + e_r)
        j = AXES.index(a)
        own = e_f[:, j] if a == "X" else mean[:, j]
        np.testing.assert_allclose([float(r[a]) for r in rows], -own, rtol=0, atol=6e-6)
        for d in AXES:
            if d != a:
                np.testing.assert_allclose([float(r[d]) for r in rows], -mean[:, AXES.index(d)],
                                           rtol=0, atol=6e-6)
        if a == "X":
            np.testing.assert_allclose([float(r["BACKLASH"]) for r in rows], -e_r[:, j], rtol=0, atol=6e-6)
        else:
            assert "BACKLASH" not in cols


# ------------------------------------------------------------------------------------ Fanuc
_FANUC_PARAMETER = re.compile(r"N(\d{5})Q1((?:A\d+P-?\d+)+)")
_FANUC_PITCH = re.compile(r"N(1\d{4})Q0P(-?\d+)")


def parse_fanuc_tape(text):
    """({(parameter, axis): value}, {point: value}) of a parameter tape; fails on any line a Fanuc
    would not read as one of these blocks (a comment, a title after '%', a missing closing '%')."""
    lines = text.split("\n")
    assert lines[-1] == "" and lines[0] == "%" and lines[-2] == "%", text[:80]
    par, data = {}, {}
    for line in lines[1:-2]:
        m = _FANUC_PARAMETER.fullmatch(line)
        if m:
            for a, v in re.findall(r"A(\d+)P(-?\d+)", m.group(2)):
                assert (int(m.group(1)), int(a)) not in par, line
                par[(int(m.group(1)), int(a))] = int(v)
            continue
        m = _FANUC_PITCH.fullmatch(line)
        assert m, f"not a block of a Fanuc parameter tape: {line!r}"
        data[int(m.group(1)) - 10000] = int(m.group(2))
    return par, data


def read_fanuc(text, unit_mm):
    """axis number -> {'+': (positions, compensation), '-': ...} from the parameters and the
    incremental pitch data (bidirectional where 3626 is given)."""
    par, data = parse_fanuc_tape(text)
    out = {}
    for (n, a) in {k for k in par if k[0] == 3620}:
        ref, lo, hi, mag, itv = (par[(3620, a)], par[(3621, a)], par[(3622, a)], par[(3623, a)],
                                 par[(3624, a)])
        pts = np.arange(lo, hi + 1)
        pos = (pts - ref) * itv * unit_mm      # the reference position is 0 in these tests

        def comp(start, offset=0):
            r = ref - lo + start
            c = []
            for k in range(start, start + len(pts)):
                if k > r:
                    c.append(sum(data[i] for i in range(r + 1, k + 1)))
                else:
                    c.append(-sum(data[i] for i in range(k + 1, r + 1)))
            return (np.array(c) + offset) * mag * unit_mm

        out[a] = {"+": (pos, comp(lo))}
        if (3626, a) in par:
            out[a]["-"] = (pos, comp(par[(3626, a)], par[(3627, a)]))
        out[a]["resolution"] = mag * unit_mm
    return out


def test_fanuc_pitch_error_parameters_reproduce_the_model(fitted, model_path, tmp_path):
    out = export(model_path, tmp_path / "fa", "fanuc", "--grid-mm", "5")
    tables = read_fanuc((out / "pitch_error.txt").read_text(), 1e-3)
    assert set(tables) == {1, 2, 3}
    for k, a in enumerate(AXES, start=1):
        pos, comp = tables[k]["+"]
        res = tables[k]["resolution"]
        assert len(pos) <= 128 and 0.0 in pos
        j = AXES.index(a)
        e_f = predicted(fitted, a, pos, 1.0)[:, j]
        ref_f = predicted(fitted, a, np.array([0.0]), 1.0)[0, j]
        if a != "X":   # no backlash: one table of the mean
            e_f = 0.5 * (e_f + predicted(fitted, a, pos, -1.0)[:, j])
            ref_f = 0.0
        # the correction, relative to the reference point moving positive; cumulative rounding
        np.testing.assert_allclose(comp, -(e_f - ref_f), rtol=0, atol=0.5 * res + 1e-9)
        if a == "X":
            pos_r, comp_r = tables[k]["-"]
            e_r = predicted(fitted, a, pos_r, -1.0)[:, j]
            np.testing.assert_allclose(comp_r, -(e_r - ref_f), rtol=0, atol=0.5 * res + 1e-9)
        else:
            assert "-" not in tables[k]
    # X reverses (its backlash is in the tables): the README says to keep 1851 at 0, once, for X
    readme = (out / "README.txt").read_text()
    assert readme.count("parameter 1851") == 1 and "axis X: the reversal (backlash)" in readme


def test_fanuc_tape_holds_only_what_a_fanuc_reads_and_the_readme_the_rest(model_path, tmp_path):
    """pitch_error.txt is a parameter tape and nothing else (every line parsed strictly above: no
    title after '%', no comment lines, the closing '%'); the bit parameter 3605 is not on it (a
    tape sets its whole byte); the README says which axes need its bit 0 and how the axes are
    numbered."""
    out = export(model_path, tmp_path / "fa", "fanuc", "--grid-mm", "5")
    text = (out / "pitch_error.txt").read_text()
    par, data = parse_fanuc_tape(text)
    assert {n for n, _ in par} == {3620, 3621, 3622, 3623, 3624, 3626, 3627}
    assert {a for n, a in par if n == 3626} == {1}          # only X has a backlash
    assert len(data) == max(data) + 1 and min(data) == 0
    readme = (out / "README.txt").read_text()
    assert "1 for X (A1) (bidirectional tables), 0 for Y (A2), Z (A3)" in readme
    assert "A1 = X, A2 = Y, A3 = Z" in readme


# ------------------------------------------------------------------------------------ ISG
def read_isg(path):
    rows = [line for line in Path(path).read_text().splitlines() if line and not line.startswith("//")]
    head = rows[0].split(",")
    data = np.array([[float(v) for v in r.split(",")] for r in rows[1:]])
    return head, data


def test_isg_volumetric_csv_holds_every_component(fitted, model_path, tmp_path):
    out = export(model_path, tmp_path / "isg", "isg")
    for a in AXES:
        head, data = read_isg(out / f"vc_{a.lower()}.csv")
        assert head == [a, f"EX{a}", f"EY{a}", f"EZ{a}", f"EA{a}", f"EB{a}", f"EC{a}"]
        pos = data[:, 0]
        mean = 0.5 * (predicted(fitted, a, pos, 1.0) + predicted(fitted, a, pos, -1.0))
        np.testing.assert_allclose(data[:, 1:4], mean, rtol=0, atol=1e-9)
        assert np.all(np.isfinite(data[:, 4:]))
        if a == "X":
            continue
        # rotations of the tool-side axes, independently: their angular errors turn the tool, so the
        # tool axis deviates by w x e_z = (w_y, -w_x, 0) (to first order; a tool's length does not
        # show them: it raises the ram, and the tip stays where it is commanded)
        m = fitted.machine
        q = np.zeros((len(pos), m.n_axes))
        q[:, m.index(a)] = np.clip(pos, *SUPPORT[a])
        c = fitted.context(len(pos), {f"dir_{a}": np.ones(len(pos))})
        da = (deviation(fitted.model, q, fitted.params.values, c)[:, 3:]
              - deviation(fitted.model, np.zeros((1, m.n_axes)), fitted.params.values, fitted.context(1))[:, 3:])
        da[beyond_the_ramp(pos, *SUPPORT[a])] = 0.0
        w_x, w_y = -da[:, 1], da[:, 0]
        np.testing.assert_allclose(data[:, 4], w_x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(data[:, 5], w_y, rtol=0, atol=1e-9)
        assert np.max(np.abs(w_x)) > 1e-6 and np.max(np.abs(w_y)) > 1e-6


def read_isg_ssfk(path):
    """(positions mm, pos values mm, neg values mm or None) of a kw.ssfk list: 'key value' lines,
    '#' comments, positions kw_startpos + i interval and values in 0.1 um (ISG's example)."""
    kv = {}
    for line in Path(path).read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            k, v = line.split()
            kv[k] = v if k == "kopf.log_achs_name" else int(v)
    n, tenth = kv["kw.ssfk.kw_nr_max"], 1e-4
    if kv["kw.ssfk.interval"] == 0:    # non-equidistant: each point's position (ISG's example)
        pos = np.array([kv[f"kw.ssfk.table[{i}].setpoint"] for i in range(n)]) * tenth
    else:
        pos = (kv["kw.ssfk.kw_startpos"] + kv["kw.ssfk.interval"] * np.arange(n)) * tenth
    up = np.array([kv[f"kw.ssfk.table[{i}].pos"] for i in range(n)]) * tenth
    down = (np.array([kv[f"kw.ssfk.table[{i}].neg"] for i in range(n)]) * tenth
            if kv["kw.ssfk.bilateral"] == 1 else None)
    return pos, up, down


def test_isg_leadscrew_lists_hold_the_error_with_backlash(fitted, model_path, tmp_path):
    out = export(model_path, tmp_path / "isg", "isg")
    for a in AXES:
        pos, up, down = read_isg_ssfk(out / f"achskw_{a.lower()}.lis")
        j = AXES.index(a)
        e_f, e_r = predicted(fitted, a, pos, 1.0)[:, j], predicted(fitted, a, pos, -1.0)[:, j]
        assert pos[1] == pytest.approx(SUPPORT[a][0], abs=1e-9)
        assert pos[-2] == pytest.approx(SUPPORT[a][1], abs=1e-9)
        assert up[0] == up[-1] == 0
        if a == "X":   # actual minus setpoint, each direction
            np.testing.assert_allclose(up, e_f, rtol=0, atol=5.1e-5)
            np.testing.assert_allclose(down, e_r, rtol=0, atol=5.1e-5)
        else:
            assert down is None
            np.testing.assert_allclose(up, 0.5 * (e_f + e_r), rtol=0, atol=5.1e-5)


def test_isg_tables_reach_the_high_end_of_the_region_like_linuxcnc(tmp_path):
    # X's data reach 55.8 mm: off the 1 mm grid from -20, so the last point is the region's end, as
    # in the LinuxCNC table; the leadscrew list then names every position
    fm = random_model("xfyz", (Backlash("X"),), 23, 40.0, {"X": (-20.0, 55.8)})
    fm.params.set_file_value("BL_X", 9.0)
    path = tmp_path / "model.json"
    save_model(path, fm)
    lcnc = read_linuxcnc_comp(export(path, tmp_path / "lcnc", "linuxcnc") / "x.comp", 1)[0]
    out = export(path, tmp_path / "isg", "isg")
    _, vc = read_isg(out / "vc_x.csv")
    pos, up, down = read_isg_ssfk(out / "achskw_x.lis")
    for grid in (vc[:, 0], pos):
        np.testing.assert_allclose(grid[[0, 1, -2, -1]], [-21.0, -20.0, 55.8, 56.8], rtol=0, atol=1e-9)
        np.testing.assert_allclose(grid, lcnc, rtol=0, atol=1e-9)
    e_f, e_r = predicted(fm, "X", pos, 1.0)[:, 0], predicted(fm, "X", pos, -1.0)[:, 0]
    np.testing.assert_allclose(up, e_f, rtol=0, atol=5.1e-5)
    np.testing.assert_allclose(down, e_r, rtol=0, atol=5.1e-5)
    np.testing.assert_allclose(vc[:, 1], 0.5 * (e_f + e_r), rtol=0, atol=1e-9)


# ------------------------------------------------------------------------------------ Klipper
def read_klipper(path):
    section, out = None, {}
    for line in Path(path).read_text().splitlines():
        line = line.split("#")[0].strip()
        if line.startswith("["):
            section = line.strip("[]")
        elif "=" in line and section == "skew_correction mtcomp":
            k, v = line.split("=")
            out[k.strip()] = float(v)
    return out


def test_klipper_skew_factors_are_the_angles_between_the_axes(fitted, model_path, tmp_path):
    out = export(model_path, tmp_path / "skew.cfg", "klipper")
    skew = read_klipper(out)
    for i, j in (("X", "Y"), ("X", "Z"), ("Y", "Z")):
        sj = np.linspace(*SUPPORT[j], 9)
        si = np.linspace(*SUPPORT[i], 9)
        a = np.polyfit(sj, predicted(fitted, j, sj)[:, AXES.index(i)], 1)[0]
        b = np.polyfit(si, predicted(fitted, i, si)[:, AXES.index(j)], 1)[0]
        assert skew[f"{i.lower()}{j.lower()}_skew"] == pytest.approx(a + b, rel=0.05, abs=1e-8)


# ------------------------------------------------------------------------------------ a rotary axis
def test_rotary_table_matches_the_laser_reading_of_its_angular_positioning(tmp_path):
    """The C table of a rotary table (CAFXYZ) against a second formulation: `mtcomp predict` of a
    laser file of ECC readings (the measurement model: actual minus commanded angle of the table)."""
    p = tmp_path / "caf.json"
    save_model(p, random_model("cafxyz", (Backlash("C"),), 2, 8.0, {"C": (-np.pi, np.pi)}))
    assert main(["export", "cafxyz", str(p), "--format", "linuxcnc", "-o", str(tmp_path / "lc"),
                 "--grid-deg", "10"]) == 0
    nom, fwd, rev = read_linuxcnc_comp(tmp_path / "lc" / "c.comp", 1)
    laser = tmp_path / "c.csv"
    laser.write_text("axis,component,target_deg,dir,run,value_urad\n" + "".join(
        f"C,ECC,{t:g},{d},1,\n" for t in [0.0, *nom] for d in (1, -1)))
    assert main(["predict", "cafxyz", str(p), str(laser), "-o", str(tmp_path / "pred.csv")]) == 0
    lines = (tmp_path / "pred.csv").read_text().splitlines()
    col = lines[0].split(",").index("pred_value_urad")
    pred = np.array([float(line.split(",")[col]) for line in lines[1:]]).reshape(-1, 2)   # (dir +1, -1)
    ref = pred[0].mean()
    urad_per_deg = np.pi / 180 * 1e6
    # trim = minus the error; 6 decimals of a degree = 0.017 urad
    np.testing.assert_allclose(-fwd * urad_per_deg, pred[1:, 0] - ref, rtol=0, atol=0.01)
    np.testing.assert_allclose(-rev * urad_per_deg, pred[1:, 1] - ref, rtol=0, atol=0.01)


def test_linuxcnc_table_applied_as_linuxcnc_does_cancels_the_positioning_error(fitted, model_path, tmp_path):
    """Closing the loop: command x + trim(x) (interpolated, forward or reverse column by direction)
    and ask the model where the axis goes; what remains is second order (the error's slope times
    the trim) plus interpolation between 1 mm grid points."""
    out = export(model_path, tmp_path / "lc", "linuxcnc")
    nom, fwd, rev = read_linuxcnc_comp(out / "x.comp", 1)
    x = np.random.default_rng(7).uniform(SUPPORT["X"][0], SUPPORT["X"][1], 200)
    for d, col in ((1.0, fwd), (-1.0, rev)):
        cmd = x + np.interp(x, nom, col)
        reached = cmd + predicted(fitted, "X", cmd, d, table=False)[:, 0]
        before = predicted(fitted, "X", x, d, table=False)[:, 0]
        assert np.max(np.abs(before)) > 5e-3
        np.testing.assert_allclose(reached, x, rtol=0, atol=2e-3 * np.max(np.abs(before)))


def test_siemens_writes_no_table_of_zeros(tmp_path):
    """A model of X positioning alone (laser runs of X: every other error held at zero) gets its LEC
    table and no cross-axis CEC table of zeros; the README says why."""
    model = ErrorModel(load_machine("xfyz").with_basis("polynomial"))
    ps = ParameterSet(model.param_specs)
    ps.set_file_value("EXX_1", 30.0)
    ps.set_file_value("EXX_2", -20.0)
    path = tmp_path / "x.json"
    save_model(path, FittedModel(model, ps, support={"X": (-100.0, 200.0)}))
    out = export(path, tmp_path / "sie", "siemens")
    cec_text = (out / "NC_CEC.INI").read_text()
    assert "$AN_CEC_OUTPUT_AXIS" not in cec_text
    assert "$AA_ENC_COMP[0,0,AX1]" in (out / "AX_EEC.INI").read_text()
    readme = (out / "README.txt").read_text()
    assert "no CEC table for AX1 -> AX2" in readme and "no CEC table for AX1 -> AX3" in readme


def test_heidenhain_cells_never_print_minus_zero():
    from mtcomp.export.heidenhain import com_table
    import numpy as np
    text = com_table("X.COM", np.array([0.0, 10.0]), {"X": np.array([-1e-7, 0.00123456])})
    assert "-0.00000" not in text
    assert "+0.00000" in text and "+0.00123" in text
