"""A shop with a CMM only: the X Y hole positions of plates drilled with tools of 100 and 200 mm at
one height, each plate aligned on the CMM (its frame fitted), identify a machine whose Z travel is
tilted (B0Z 20 urad, A0Z -10 urad: a longer tool's tip stands off in X Y) with a pitch of X and a
bow of Y. A part is then cut under G54 with tools of 100, 200 and 260 mm; the part's datum was
probed once in X and Y with a 100 mm probe, and each tool set in Z on its own.

The oracle is the independent machine (tests/truth, no mtcomp code): the tip's X Y deviation at
each corrected block less that of the probe's tip at the datum, which the probed offset holds."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from mtcomp.cli import main
from truth import TruthMachine
from truth import profiles as P

Z_DATA = -150.0                     # the plates' tip height (machine), the part's program Z0
G54 = np.array([0.0, 0.0, Z_DATA])
PROBE = 100.0
TOOLS = {1: 100.0, 2: 200.0, 3: 260.0}
HOLES = [(-80.0, -60.0), (80.0, -60.0), (80.0, 60.0), (-80.0, 60.0), (0.0, 0.0)]


def _truth():
    m = TruthMachine.zero("xfyz")
    m.squareness["B0Z"] = 20e-6
    m.squareness["A0Z"] = -10e-6
    m.components["X"]["EXX"] = P.Linear(12e-6)
    m.components["Y"]["EXY"] = P.Sines((3e-3,), (500.0,), (0.0,))
    return m


def _plate(path, m, seed):
    rng = np.random.default_rng(seed)
    grid = np.meshgrid(np.arange(-120.0, 120.1, 40.0), np.arange(-90.0, 90.1, 30.0))
    x, y = (v.ravel() for v in grid)
    tool = np.where(np.arange(x.size) % 2 == 0, 100.0, 200.0)
    q = np.column_stack([x, y, np.full(x.size, Z_DATA)])
    d = np.array([m.true_deviation(q[i:i + 1], tool[i])[0][0] for i in range(x.size)]) * 1e3
    rz, t = rng.normal(0.0, 30e-6), rng.normal(0.0, 5.0, 2)      # the plate's CMM alignment
    d[:, 0] += t[0] - rz * y * 1e3 + rng.normal(0.0, 0.2, x.size)
    d[:, 1] += t[1] + rz * x * 1e3 + rng.normal(0.0, 0.2, x.size)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["x_mm", "y_mm", "z_mm", "tool_mm", "dx_um", "dy_um"])
        for row in zip(x, y, q[:, 2], tool, d[:, 0], d[:, 1]):
            w.writerow([f"{v:.4f}" for v in row])
    return path


def _program(path, blocks):
    """blocks: (tool, program z) pairs: each tool drills HOLES (G81) to that z."""
    lines = ["G21 G90 G17 G40 G49 G80"]
    for tool, z in blocks:
        lines += [f"T{tool} M6", "G54", f"G0 X{HOLES[0][0]:g} Y{HOLES[0][1]:g}", f"G43 Z20 H{tool}",
                  f"G98 G81 X{HOLES[0][0]:g} Y{HOLES[0][1]:g} Z{z:g} R5 F200"]
        lines += [f"X{x:g} Y{y:g}" for x, y in HOLES[1:]]
        lines += ["G80", "G0 Z50"]
    lines.append("M30")
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def plates(tmp_path_factory):
    d = tmp_path_factory.mktemp("cram")
    m = _truth()
    a, b = _plate(d / "plate_a.csv", m, 1), _plate(d / "plate_b.csv", m, 2)
    model = d / "m.json"
    assert main(["identify", "xfyz", str(a), str(b), "-o", str(model)]) == 0
    return d, m, model


def _compensate(d, model, blocks, tag, *flags):
    prog = _program(d / f"{tag}.nc", blocks)
    report, summary = d / f"{tag}.csv", d / f"{tag}.json"
    args = ["compensate", "xfyz", str(model), str(prog), "-o", str(d / f"{tag}_out.nc"),
            "--report", str(report), "--work-offset", "G54=X0,Y0,Z%g" % Z_DATA]
    args += [f"--tool-length=H{k}={v:g}" for k, v in TOOLS.items()] + list(flags)
    assert main(args) == 0
    with open(report) as f:
        rows = [r for r in csv.DictReader(f) if r["inserted"] == "0" and r["rapid"] == "0"]
    return rows


def _holes_after_um(m, rows, tool, probe=PROBE):
    """(n, 2) um: the X Y error of the tip at each hole's bottom as corrected, relative to the probe's
    tip at the datum (what the probed offset holds), on the independent machine. BLOCKS.csv's
    positions are the corrected ones (the program as written), its corrections cx_um ... apart."""
    q = np.array([[float(r["x_mm"]), float(r["y_mm"]), float(r["z_mm"])] for r in rows]) + G54
    c = np.array([[float(r[k] or 0.0) for k in ("cx_um", "cy_um", "cz_um")] for r in rows]) * 1e-3
    dev = m.true_deviation(q, tool)[0] + c            # the tip less the program's (q - c) point
    datum = m.true_deviation(G54[None, :], probe)[0][0]
    return (dev - datum)[:, :2] * 1e3


def _uncorrected(rows):
    """The rows as the program wrote them, uncorrected (positions less their corrections)."""
    out = []
    for r in rows:
        c = {k: float(r[f"c{k}_um"] or 0.0) * 1e-3 for k in "xyz"}
        out.append(dict(r, cx_um=0, cy_um=0, cz_um=0,
                        **{f"{k}_mm": float(r[f"{k}_mm"]) - c[k] for k in "xyz"}))
    return out


def test_each_tool_is_referenced_to_the_probe_s_tip_in_x_and_y(plates, capsys):
    """The 200 mm tool, a length the plates measured, at their height: its tip stands off the
    probe's at the datum by B0Z 100 mm = 2 um in X and -A0Z 100 mm = 1 um in Y (by hand), which
    the datum probed once in X Y does not hold. Referencing each tool to its own tip at the datum left that between the
    holes of the two tools (2.2 um); now they agree to 0.3 um. (A rotation of the whole part the
    CMM data cannot tell from the plates' alignment is common to both tools.)"""
    d, m, model = plates
    rows = _compensate(d, model, [(1, 0.0), (2, 0.0)], "ref")
    assert "note: the program's tools" not in capsys.readouterr().out     # the data's 100, 200 mm
    assert len(rows) == 2 * len(HOLES) and all(r["corrected"] == "1" for r in rows), rows
    t1, t2 = rows[:len(HOLES)], rows[len(HOLES):]
    uncorrected = _uncorrected(t1 + t2)
    before = (_holes_after_um(m, uncorrected[len(HOLES):], 200.0)
              - _holes_after_um(m, uncorrected[:len(HOLES)], 100.0))
    np.testing.assert_allclose(before, np.tile([2.0, 1.0], (len(HOLES), 1)), atol=0.01)
    between = _holes_after_um(m, t2, 200.0) - _holes_after_um(m, t1, 100.0)
    assert np.max(np.hypot(*between.T)) < 0.3, between


def test_a_ram_outside_the_data_leaves_only_its_own_correction(plates, capsys):
    """Holes drilled 10 mm below the plates with the 100 mm tool (the ram at -160, below the -150
    .. -50 mm the data reached) and at their height with a 260 mm tool (the ram at +10, above it):
    the X Y errors there are the table's and the saddle's, which the plates measured, and the tilt
    of Z's straight line in the tool length. Left uncorrected whole before (3.6 um for the long
    tool, against the probe); now X and Y are corrected, Z is not, and the summary says where the
    ram stood against where its data reached, and that the 260 mm tool is longer than the data's."""
    d, m, model = plates
    rows = _compensate(d, model, [(1, 0.0), (1, -10.0), (3, 0.0)], "ram")
    out = capsys.readouterr().out
    n = len(HOLES)
    ref, deep, long_ = rows[:n], rows[n:2 * n], rows[2 * n:]
    assert all(r["outside_support"] == "Z" and r["corrected"] == "1" for r in deep + long_), rows
    assert all(float(r["cz_um"] or 0.0) == 0.0 for r in deep + long_), rows
    said = "with the ram (Z) outside the -150 .. -50 mm its data reached (at -160 .. 60 mm"
    assert said in out, out
    said = ("note: the program's tools are 100 .. 260 mm long, the model's data were taken with "
            "100 .. 200 mm")
    assert said in out, out
    base = _holes_after_um(m, ref, 100.0)                 # the part's rotation, common to all
    for part, tool, before_um, tol in ((deep, 100.0, 1.0, 0.4), (long_, 260.0, 3.0, 0.8)):
        zero = _uncorrected(part)
        assert np.max(np.hypot(*_holes_after_um(m, zero, tool).T)) > before_um
        err = np.hypot(*(_holes_after_um(m, part, tool) - base).T)
        assert np.max(err) < tol, (tool, err)


def test_the_probe_s_length_is_given(plates):
    """The datum found with a 200 mm probe: the hole at the datum (X0 Y0 at the plates' height,
    where the part's rotation moves nothing) lands on the probe's point with either tool, the
    100 mm drill's standing 2.2 um off it uncorrected."""
    d, m, model = plates
    rows = _compensate(d, model, [(1, 0.0), (2, 0.0)], "probe200", "--probed-with-tool-length", "200")
    at_datum = [r for r in rows if abs(float(r["x_mm"])) < 0.01 and abs(float(r["y_mm"])) < 0.01]
    assert len(at_datum) == 2, rows
    zero = _uncorrected(at_datum[:1])
    np.testing.assert_allclose(_holes_after_um(m, zero, 100.0, probe=200.0), [[-2.0, -1.0]], atol=0.01)
    for r, tool in zip(at_datum, (100.0, 200.0)):
        assert np.hypot(*_holes_after_um(m, [r], tool, probe=200.0)[0]) < 0.3, (tool, r)
