"""What keeps a compensation fast gives the plan of the plain way: the datum's distinct rows found
from runs of equal rows against numpy's unique over every row and against evaluating every row, a
program read in small chunks in a thread of its own and planned in parts against one chunk in one
thread (byte for byte), and ``compensate`` importing none of the fitting packages."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mtcomp.compensation import CompensationSettings, compensate_program
from mtcomp.planner import CompensationProblem
from mtcomp.planner import _parallel
from mtcomp.planner._evaluate import Evaluator, _unique_rows
from mtcomp.toolpaths.offsets import load_setup

from test_planner_core import fitted_model


def _runs(rng, n, distinct):
    """(n, k) rows drawn from ``distinct`` (m, k) in runs of 1 to 40 equal rows."""
    pick = [np.zeros(0, int)]
    while sum(len(p) for p in pick) < n:
        pick.append(np.full(int(rng.integers(1, 41)), rng.integers(len(distinct))))
    return distinct[np.concatenate(pick)[:n]]


@pytest.mark.parametrize("n", [0, 1, 2, 500])
def test_unique_rows_match_numpy_over_every_row(n):
    rng = np.random.default_rng(n + 5)
    distinct = np.round(rng.normal(size=(7, 4)), 1)
    distinct[3] = distinct[1]                       # equal rows under two labels
    distinct[4, :3] = distinct[2, :3]               # rows that differ in the last column only
    a = _runs(rng, n, distinct)
    uniq, inv = _unique_rows(a)
    want_u, want_i = np.unique(a, axis=0, return_inverse=True)
    np.testing.assert_array_equal(uniq, want_u)
    np.testing.assert_array_equal(inv, want_i.reshape(-1))
    np.testing.assert_array_equal(uniq[inv], a)


def test_datum_reference_is_the_deviation_at_each_rows_datum():
    """Evaluated once per distinct (datum, tool length) and spread over the blocks: the same as the
    model's deviation at every block's own datum (evaluated row by row here)."""
    fitted = fitted_model("xfyz", 12)
    ev = Evaluator(CompensationProblem.from_machine(fitted))
    rng = np.random.default_rng(4)
    # the last datum twice, with another tool length: a run that changes only in its tool
    datums = np.array([[0.0, 0.0, 0.0], [120.0, -40.0, -100.0], [-250.0, 80.0, 20.0],
                       [-250.0, 80.0, 20.0]])
    tools = np.array([0.0, 35.0, 35.0, 80.0])
    pick = _runs(rng, 300, np.column_stack([datums, tools]))
    names = fitted.model.context_names
    ctx = fitted.context(300, {"tool_length": pick[:, 3]} if "tool_length" in names else None)
    got = ev.datum_reference(pick[:, :3], ctx)
    tool = ctx[:, names.index("tool_length")] if "tool_length" in names else np.zeros(300)
    want = np.vstack([fitted.at_datum("deviation_function", pick[i:i + 1, :3], tool[i:i + 1])
                      for i in range(300)])[:, :3]
    np.testing.assert_allclose(got[:, :3], want, rtol=0, atol=1e-15)
    assert np.ptp(got[:, 0]) > 1e-4                 # the datums differ in their deviation
    same = np.all(pick[:, :3] == datums[2], axis=1)
    assert np.ptp(tool[same]) > 0 and np.ptp(got[same, :3], axis=0).max() > 1e-6   # tools too
    np.testing.assert_array_equal(got[:, 3:], 0.0)


def _program(path: Path, n: int, seed: int = 3) -> None:
    """Feed moves in two work offsets (G54, G55 switching every few hundred blocks), an arc and a
    rapid now and then, a comment line: many runs of datums, chunks cut anywhere."""
    rng = np.random.default_rng(seed)
    xyz = np.cumsum(rng.normal(0.0, 0.4, (n, 3)), axis=0) + [0.0, 0.0, -60.0]
    lines = ["%", "G21 G90 G17", "G54", "G0 X0 Y0 Z-60", "G1 F1200"]
    for i, (x, y, z) in enumerate(xyz):
        if i % 311 == 0 and i:
            lines.append("G55" if (i // 311) % 2 else "G54")
            lines.append(f"G0 X{x:.4f} Y{y:.4f} Z{z:.4f}")
            lines.append("G1 F1200")
        elif i % 97 == 0 and i:
            s, e = xyz[i - 1, :2], np.array([x, y])
            perp = np.array([s[1] - e[1], e[0] - s[0]]) / np.linalg.norm(e - s)
            ij = 0.5 * (e - s) + 3.0 * perp            # the centre 3 mm off the chord's middle
            lines.append(f"G2 X{x:.4f} Y{y:.4f} I{ij[0]:.4f} J{ij[1]:.4f}")
            lines.append("G1")
            continue
        lines.append(f"X{x:.4f} Y{y:.4f} Z{z:.4f}")
        if i % 500 == 0:
            lines.append("(PASS)")
    lines += ["M30", "%"]
    path.write_text("\n".join(lines) + "\n")


def test_small_chunks_threads_and_parts_write_the_same_program(tmp_path, monkeypatch):
    """A program compensated in chunks of 200 rows read in a thread of its own, with its per-block
    work cut into parts for threads, writes the program and report of one chunk in one thread."""
    import mtcomp.compensation as compensation
    fitted = fitted_model("xfyz", 21)
    prog = tmp_path / "p.nc"
    _program(prog, 3000)
    setup = load_setup(fitted.machine, None, ["G55=X150,Y-60,Z-20"], [])
    outputs = {}
    for name, rows, threads in (("whole", 10 ** 6, 1), ("chunked", 200, 3)):
        monkeypatch.setattr(compensation, "CHUNK_ROWS", rows)
        monkeypatch.setattr(_parallel, "MIN_PART", 50 if threads > 1 else 8192)
        out, rep = tmp_path / f"{name}.nc", tmp_path / f"{name}.csv"
        run = compensate_program(fitted, prog, out, CompensationSettings(threads=threads),
                                 setup, report=rep)
        outputs[name] = (out.read_bytes(), rep.read_bytes(), run.summary.as_dict())
    whole, chunked = outputs["whole"], outputs["chunked"]
    assert whole[0] == chunked[0]
    assert whole[1] == chunked[1]
    # the summary's sums of squares add up chunk by chunk: equal up to rounding
    flat = [{f"{k}.{j}": v for k, d in o[2].items() for j, v in
             (d.items() if isinstance(d, dict) else [("", d)])} for o in (whole, chunked)]
    assert flat[0].keys() == flat[1].keys()
    for key, v in flat[0].items():
        if isinstance(v, float):
            np.testing.assert_allclose(flat[1][key], v, rtol=1e-12, atol=0, err_msg=key)
        else:
            assert flat[1][key] == v, key
    assert whole[0] != prog.read_bytes()            # corrections were written
    assert b"G2 " in whole[0]                         # the arcs stayed arcs


def test_compensate_imports_none_of_the_fitting(tmp_path):
    """The thermal package's fitting (and with it diagnose, scipy.signal and scipy.optimize) is
    imported on first use only: a compensation reads the model's thermal context alone. So are the
    other commands (export's tables, identification), the readers of the other languages
    (Heidenhain, Sinumerik, LinuxCNC O-words, Fanuc macros) and the test-part programs: a plain
    G-code program is compensated without them."""
    prog = tmp_path / "p.nc"
    _program(prog, 50)
    model = tmp_path / "m.json"
    from mtcomp.models import save_model
    save_model(model, fitted_model("xfyz", 2))
    code = ("import sys\nfrom mtcomp.cli import main\n"
            f"assert main(['compensate', 'xfyz', {str(model)!r}, {str(prog)!r}, '-o', "
            f"{str(tmp_path / 'out.nc')!r}, '--quiet']) == 0\n"
            "print(sorted(m for m in ('mtcomp.thermal._fit', 'mtcomp.diagnose', 'scipy.signal', "
            "'scipy.optimize', 'cvxpy', 'pyvista', 'matplotlib', 'mtcomp.export', "
            "'mtcomp.identification', 'mtcomp.commands.export', 'mtcomp.commands.identify', "
            "'mtcomp.toolpaths.heidenhain', 'mtcomp.toolpaths.heidenhain_out', "
            "'mtcomp.toolpaths.sinumerik', 'mtcomp.toolpaths.sinumerik_out', "
            "'mtcomp.toolpaths.ngc', 'mtcomp.toolpaths.macro', 'mtcomp.toolpaths.parts') "
            "if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]"
    import mtcomp.thermal as thermal
    assert thermal.fit_ridge.__module__ == "mtcomp.thermal._fit"
    assert thermal.diagnose_with_record.__name__ == "diagnose_with_record"
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        thermal.nothing
