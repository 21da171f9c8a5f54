"""Fixed-format numbers read in the format the machine file gives (``fixed_format = "3.4"``) and
written back in it (docs/toolpaths.md, "Fixed-format numbers").

The oracle: the same program written with decimal points, compensated on the same machine without
the format, gives the same corrections to the format's resolution (0.0001 in); the fixed-format
words are read back here by the format's rule (the point after the first three digits), written
independently of mtcomp's reader."""
import contextlib
import io
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model

#: the Monarch post's words (Siemens NX, GE 1050 control): 3.4 with leading zeros, trailing zeros
#: left off (`Z-0005` is -0.5, `I-001` is -1), the feed F0098 9.8 in/min
FIXED = """%
N0010G20G90G17
N0020G00X0019685Y-0008937Z001
N0030G01Z-0005F0098
N0040X0043307
(an arc of radius 1 about X3.3307 Y-0.8937)
N0050G03X0033307Y0001063I-001J0
N0060G00Z001
N0070M30
%
"""
DECIMAL = """%
N0010G20G90G17
N0020G00X1.9685Y-0.8937Z1.
N0030G01Z-0.5F9.8
N0040X4.3307
(an arc of radius 1 about X3.3307 Y-0.8937)
N0050G03X3.3307Y0.1063I-1.J0
N0060G00Z1.
N0070M30
%
"""
_WORD = re.compile(r"([XYZIJ])([-+]?[\d.]+)")


def _machine(tmp_path, fixed: bool):
    text = 'name = "t"\ntopology = "XFYZ"\n' + 'fixed_format = "3.4"\n' * fixed + "".join(
        f"[axes.{a}]\ntravel_mm = [-5000.0, 5000.0]\n" for a in "XYZ")
    path = tmp_path / f"m{int(fixed)}.toml"
    path.write_text(text)
    return path


def _model(tmp_path, machine):
    """Errors about 30 times the usual size: corrections of several 0.0001 in."""
    model = ErrorModel(load_machine(machine))
    fitted = FittedModel.zero(model)
    scale = {"um": 0.09, "urad": 1.5e-4, "mm": 50.0, "1": 0.05}
    fitted.params.values[:] = np.random.default_rng(1).normal(size=model.n_params) * np.array(
        [scale[s.unit] for s in model.param_specs])
    save_model(tmp_path / "model.json", fitted)
    return tmp_path / "model.json"


def _compensate(tmp_path, machine, model, text, name):
    src = tmp_path / name
    src.write_text(text)
    out = tmp_path / f"out-{name}"
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(["compensate", str(machine), str(model), str(src), "-o", str(out), "--quiet"])
    return code, err.getvalue(), out


def _fixed_value(number: str) -> float:
    """The format's reading: the point after the first three digits."""
    sign = -1.0 if number.startswith("-") else 1.0
    digits = number.lstrip("+-")
    return sign * int(digits) * 10.0 ** (3 - len(digits))


def test_a_fixed_format_program_gets_the_corrections_of_its_decimal_twin(tmp_path):
    fixed_m, plain_m = _machine(tmp_path, True), _machine(tmp_path, False)
    model = _model(tmp_path, plain_m)
    code, err, fixed_out = _compensate(tmp_path, fixed_m, model, FIXED, "fixed.nc")
    assert code == 0, err
    code, err, plain_out = _compensate(tmp_path, plain_m, model, DECIMAL, "plain.nc")
    assert code == 0, err
    got, want = fixed_out.read_text().splitlines(), plain_out.read_text().splitlines()
    src, dec = FIXED.splitlines(), DECIMAL.splitlines()
    assert len(got) == len(want) == len(src)
    moved = 0
    for g, w, s, d in zip(got, want, src, dec):
        if w == d:
            assert g == s               # a line without a correction: as written
            continue
        gw, ww = _WORD.findall(g), _WORD.findall(w)
        assert [letter for letter, _ in gw] == [letter for letter, _ in ww], (g, w)
        for (letter, number), (_, decimal) in zip(gw, ww):
            # in the format: no point, three digits before it (a zero may be 0)
            assert re.fullmatch(r"-?(?:0|\d{3}\d{0,4})", number), number
            # the program leaves trailing zeros off after the point, and so does its output
            assert len(number.lstrip("-")) <= 3 or not number.endswith("0"), number
            # the same correction to the format's resolution, 0.0001 in
            np.testing.assert_allclose(_fixed_value(number), float(decimal), rtol=0,
                                       atol=0.5e-4 + 1e-9, err_msg=f"{letter}: {g} / {w}")
        # a word whose value the correction leaves is written as the program wrote it
        written = dict(gw)
        for letter, number in _WORD.findall(s):
            if abs(_fixed_value(written[letter]) - _fixed_value(number)) < 1e-9:
                assert written[letter] == number, (letter, g, s)
        moved += g != s
    assert moved >= 4
    assert "F0098" in got[3]        # the feed passes through in its own format


def test_without_the_format_the_program_is_refused_naming_the_setting(tmp_path):
    machine = _machine(tmp_path, False)
    code, err, out = _compensate(tmp_path, machine, _model(tmp_path, machine), FIXED, "p.nc")
    assert code == 2 and not out.exists() and len(err.strip().splitlines()) == 1
    assert "p.nc:3: X0019685 is a fixed-format number" in err
    assert 'fixed_format = "3.4"' in err and "Traceback" not in err


@pytest.mark.parametrize("line, words", [
    # the GE 1050's own moves along the spindle, as the Monarch post writes them
    ("N0035G87R-0003937Z-0003937F600D01", ":6: G87 in a program read in the fixed format 3.4"),
    ("N0035G86R-0001181Z0F0098", ":6: G86 in a program read in the fixed format 3.4"),
    ("N0035G01X1.5", ":6: X1.5 has a decimal point in a program read in the fixed format 3.4"),
    ("N0035G01X00196851", ":6: X00196851 has more digits than the fixed format 3.4"),
    ("N0035G01A0900000", ":6: A0900000 has no decimal point"),
    # a format that leaves leading zeros off (X5 for 0.0005, counted from the right) is another
    ("N0035G01X5", ":6: X5 has fewer digits than the 3 before the point of the fixed format 3.4"),
])
def test_what_the_format_does_not_read_is_refused_at_its_line(tmp_path, line, words):
    machine = _machine(tmp_path, True)
    text = FIXED.replace("N0040X0043307\n", f"N0040X0043307\n{line}\n")
    code, err, out = _compensate(tmp_path, machine, _model(tmp_path, machine), text, "p.nc")
    assert code == 2 and not out.exists() and len(err.strip().splitlines()) == 1, err
    assert words in err, err


def test_the_machine_file_says_the_format_as_digits_before_and_after_the_point(tmp_path):
    assert load_machine(_machine(tmp_path, True)).fixed_format == (3, 4)
    bad = tmp_path / "bad.toml"
    bad.write_text(_machine(tmp_path, True).read_text().replace('"3.4"', "3.4"))
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(["compensate", str(bad), "m.json", "p.nc", "-o", str(tmp_path / "o.nc")])
    assert code == 2 and "fixed_format must be a string" in err.getvalue()
