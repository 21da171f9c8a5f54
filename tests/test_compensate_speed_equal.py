"""compensate's fast paths write what its plain paths write, byte for byte: the compiled reader,
writer and BLOCKS.csv formatter against the pure-Python ones (``MTCOMP_NO_FAST_GCODE=1``) on a few
programs, the formatter against Python's ``%`` on awkward numbers, and the small helpers the speed
work added against numpy and a regular expression."""
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.models import compiled
from mtcomp.planner._small import any_rows
from mtcomp.toolpaths import _fast

from test_gcode_corpus import CORPUS, _machine_file, _model_file

needs_fast = pytest.mark.skipif(not _fast.available(), reason="no compiled G-code path here")


def _program(path, n=400, seed=5):
    """Feed moves with arcs, rapids and comments; Z not given before the fifth line (blank
    report cells), small steps (some blocks hit a tight step bound)."""
    rng = np.random.default_rng(seed)
    lines = ["%", "(speed-equal test)", "G21 G90 G17", "G0 X10 Y10", "G1 Z-1 F800"]
    x, y = 10.0, 10.0
    for i in range(n):
        if i % 50 == 25:             # a half circle from where the tool stands
            lines.append(f"G2 X{x + 3:.4f} Y{y:.4f} I1.5 J0")
            x += 3
            continue
        x = round(x + rng.normal(0, 0.7), 3)
        y = round(y + rng.normal(0, 0.7), 3)
        if i % 97 == 0:
            lines.append(f"G0 X{x:.3f} Y{y:.3f}\n(move {i})")
        else:
            lines.append(f"G1 X{x:.4f} Y{y:.4f} Z{-1 + 0.01 * (i % 7):.4f}")
    lines += ["G0 Z10", "M30", "%"]
    path.write_text("\n".join(lines) + "\n")
    return path


def _with_covariance(machine_path, tmp_path):
    """A model of random parameters with a diagonal covariance: every block gets a standard error
    (the sd column), and the larger ones leave their block uncorrected."""
    from mtcomp.machine import load_machine
    from mtcomp.models import ErrorModel, FittedModel, save_model
    model = ErrorModel(load_machine(machine_path))
    fitted = FittedModel.zero(model)
    rng = np.random.default_rng(8)
    scale = np.array([{"um": 3e-3, "urad": 5e-6, "mm": 50.0, "1": 0.05}[s.unit]
                      for s in model.param_specs])
    fitted.params.values[:] = 30.0 * rng.normal(size=model.n_params) * scale
    fitted.uncertainty = {"names": list(fitted.params.names),
                          "covariance": np.diag(scale ** 2),
                          "undetermined": np.zeros((model.n_params, 0))}
    path = tmp_path / "model_cov.json"
    save_model(path, fitted)
    return path


def _run(args, monkeypatch, plain):
    if plain:
        monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
    else:
        monkeypatch.delenv("MTCOMP_NO_FAST_GCODE", raising=False)
    assert main(args) == 0


@needs_fast
@pytest.mark.parametrize("name", ["generated", "cncjs_jsdc.gcode", "linuxcnc_arcspiral.ngc"])
def test_fast_and_plain_paths_write_the_same_bytes(name, tmp_path, monkeypatch, capsys):
    prog = _program(tmp_path / "p.nc") if name == "generated" else CORPUS / name
    machine = _machine_file(tmp_path, "XFYZ")
    model = _with_covariance(machine, tmp_path) if name == "generated" else \
        _model_file(tmp_path, machine, factor=3.0)
    outs = {}
    for plain in (False, True):
        tag = "plain" if plain else "fast"
        out, rep = tmp_path / f"{tag}.nc", tmp_path / f"{tag}.csv"
        _run(["compensate", str(machine), str(model), str(prog), "-o", str(out), "--quiet",
              "--units", "mm", "--max-step-um", "0.5", "--max-correction-sd-um", "0.06",
              "--report", str(rep)], monkeypatch, plain)
        outs[tag] = (out.read_bytes(), rep.read_bytes())
    capsys.readouterr()
    assert outs["fast"][0] == outs["plain"][0]
    assert outs["fast"][1] == outs["plain"][1]
    report = outs["fast"][1].decode().splitlines()
    # the rows the compiled formatter leaves to Python are there: a bound that acted, and (the
    # generated program) blank cells where Z was not known
    assert any("step_" in row for row in report[1:]), "no block hit the step bound"
    if name == "generated":
        header = report[0].split(",")
        rows = [dict(zip(header, r.split(","))) for r in report[1:]]
        assert any(r["unknown_axes"] == "Z" and r["z_mm"] == "" for r in rows)
        # standard errors written, and some blocks left uncorrected for theirs
        assert all(r["correction_sd_um"] for r in rows if not r["unknown_axes"])
        assert any(r["uncertain"] == "1" for r in rows)


@needs_fast
def test_format_table_writes_what_python_percent_writes():
    rng = np.random.default_rng(11)
    n = 20000
    exact = np.round(rng.normal(0, 100, n), 4)
    values = np.concatenate([
        rng.normal(0, 1, n), rng.normal(0, 1e5, n), rng.normal(0, 1e12, n),
        exact + 5e-5, exact - 5e-5,                   # near ties of the fourth decimal
        np.array([np.nan, -np.nan, np.inf, -np.inf, 0.0, -0.0, -1e-9, 1e-9, 0.5, 1.5, 2.5, -0.5,
                  0.125, 0.375, -2.675, 1e300, -1e300, 5e-5, -5e-5, 123456789.123456])])
    for dec in range(7):
        got = _fast.format_table(values[:, None], [dec], [False])
        want = "".join(f"%.{dec}f\n" % v for v in values.tolist())
        assert got == want, dec
    # several columns: empty fields, NaN left blank where asked
    table = np.array([[1.0, np.nan, 2.5, np.nan], [-0.0, 3.0, np.inf, 7.0]])
    assert _fast.format_table(table, [0, 4, -1, 4], [False, False, False, True]) == \
        "1,nan,,\n-0,3.0000,,7.0000\n"


def test_any_rows_matches_numpy():
    rng = np.random.default_rng(2)
    for shape in [(50, 3), (50, 3, 5), (0, 3), (7, 1)]:
        a = rng.random(shape) < 0.05
        np.testing.assert_array_equal(any_rows(a), a.any(axis=tuple(range(1, a.ndim))))
        z = np.zeros(shape, bool)
        np.testing.assert_array_equal(any_rows(z), np.zeros(shape[0], bool))
    flags = rng.random((30, 3, 5)) < 0.1
    np.testing.assert_array_equal(any_rows(flags[:, :, 2]), flags[:, :, 2].any(axis=1))


def test_distinct_work_systems_and_tools_are_numpys_unique():
    from mtcomp.toolpaths.offsets import _distinct
    rng = np.random.default_rng(6)
    for n, runs in [(0, 1), (1, 1), (500, 1), (500, 4), (500, 400)]:
        cuts = np.sort(rng.integers(0, n + 1, runs - 1))        # runs of equal values
        a = np.repeat(rng.integers(0, 9, runs), np.diff(np.r_[0, cuts, n]))
        assert _distinct(a) == np.unique(a).tolist()


@pytest.mark.parametrize("compiled", [True, False])
def test_g_codes_match_a_regular_expression(compiled, monkeypatch):
    """In C and in numpy, over a text's first n bytes (those after read as a space)."""
    from mtcomp.compensation import _g_codes
    if compiled and not _fast.available():
        pytest.skip("no compiled G-code path here")
    if not compiled:
        monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
    rng = np.random.default_rng(4)
    alphabet = list(b"gG0124. X\n")
    codes = [b"20", b"21", b"41", b"42"]
    for _ in range(3000):
        text = bytes(rng.choice(alphabet, int(rng.integers(0, 14))).tolist())
        n = int(rng.integers(0, len(text) + 1))
        want = {c for c in codes
                if re.search(rb"[Gg]0{0,2}" + c + rb"(?![0-9.])", text[:n])}
        assert _g_codes(text, codes, n) == want, (text, n)


def test_sd_gate_jacobian_compiles_from_a_few_thousand_poses(monkeypatch):
    """The parameter Jacobian of the tip (the standard-error check of compensate) is compiled once
    a process has evaluated it on MIN_POSES_OF poses, far fewer than the other functions need."""
    monkeypatch.delenv("MTCOMP_COMPILE_MIN_POSES", raising=False)
    asked = []
    monkeypatch.setattr(compiled, "get_compiled",
                        lambda model, name, function, compile_if_missing=True:
                        asked.append((name, compile_if_missing)))
    monkeypatch.setattr(compiled, "_poses_used", {})

    class Model:
        def structure_key(self):
            return "k"
    q, p, c = np.zeros((2500, 3)), np.zeros(1), np.zeros((2500, 1))
    for name in ("tip_pjacobian_function", "deviation_function"):
        compiled.call(Model(), name, None, q, p, c)
        compiled.call(Model(), name, None, q, p, c)
    assert compiled.MIN_POSES_OF["tip_pjacobian_function"] == 5000
    assert asked == [("tip_pjacobian_function", False), ("tip_pjacobian_function", True),
                     ("deviation_function", False), ("deviation_function", False)]


def test_arc_directions_match_the_segment_by_segment_loop():
    """ModalState._directions over an arc's chords (vectorised) gives what the loop over its
    segments gave: each axis the sign of its last move, a fresh axis 0 until it moves again."""
    from mtcomp.toolpaths.modal import ModalState
    from mtcomp.toolpaths.words import DIR_EPS

    def loop(dirs, start, pts, fresh):
        step = pts - np.vstack([start[None, :], pts[:-1]])
        sign = np.where(step > DIR_EPS, 1, np.where(step < -DIR_EPS, -1, 0))
        out, cur = np.empty(sign.shape, np.int8), dirs.copy()
        for r in range(sign.shape[0]):
            cur[sign[r] != 0] = sign[r][sign[r] != 0]
            if r == 0 and fresh is not None:
                cur[fresh] = 0
            out[r] = cur
        return out

    class State:                # what _directions reads: no local frame, the directions so far
        local = type("NoFrame", (), {"kind": 0})()

    rng = np.random.default_rng(9)
    for _ in range(400):
        na, k = int(rng.integers(1, 6)), int(rng.integers(2, 8))
        state = State()
        state.dirs = rng.integers(-1, 2, na).astype(np.int8)
        start = rng.normal(size=na)
        pts = start + np.cumsum(rng.choice([0.0, 0.0, 1.0, -1.0], size=(k, na)), axis=0)
        fresh = None if rng.random() < 0.5 else rng.random(na) < 0.5
        want = loop(state.dirs, start, pts, fresh)
        got = ModalState._directions(state, start, pts, fresh)
        assert got.dtype == np.int8
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(state.dirs, want[-1])
