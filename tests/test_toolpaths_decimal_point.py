"""A Fanuc or Haas dimension word without a decimal point (a new user's finding): `G01 X60` in a
Fanuc program was read as 60 mm and written `X59.9984`. A Fanuc reads X60 as 0.060 mm under G21
(0.0060 in under G20) unless calculator-type input is set (parameter 3401#0, Fanuc Series 0i-MODEL F
operator's manual, decimal point programming; a Haas likewise unless Setting 162, Default To
Float, is on), a setting the program does not show; the corrected word, written with a point, is
read as mm by either. Refused now, with the word and the line; zero, a dwell's time, a cycle's
repeat count and codes' own numbers stay accepted."""
from __future__ import annotations

import re

import numpy as np
import pytest

from mtcomp.cli import main
from test_compensate_cli import _model

HEAD = "%\nO1000\nG21 G17 G40 G80 G90\nG54\n"
TAIL = "M30\n%\n"


def _run(tmp_path, body, dialect=None):
    prog, out = tmp_path / "p.nc", tmp_path / "out.nc"
    prog.write_text(HEAD + body + TAIL)
    rc = main(["compensate", "xfyz", str(_model(tmp_path, "xfyz", scale=0.1)[2]), str(prog), "-o", str(out), "--quiet",
               *(["--dialect", dialect] if dialect else [])])
    return rc, out


@pytest.mark.parametrize("dialect", [None, "fanuc", "haas"])
@pytest.mark.parametrize("body, line, word", [
    ("G00 X0. Y0. Z25.\nG01 X60 F1200.\n", 6, "X60"),                     # the user's line
    ("G00 X10. Y0. Z25.\nG01 Z-5.\nG02 X20. Y10. I10 J0.\n", 7, "I10"),      # an arc's centre
    ("G00 X0. Y0. Z25.\nG83 X10. Y10. Z-20. R2. Q5 F100.\n", 6, "Q5"),       # a peck depth
    ("G00 X0. Y0. Z25.\nG81 X10. Y10. Z-20. R2 F100.\n", 6, "R2"),           # a cycle's R level
])
def test_a_dimension_word_without_a_point_is_refused_naming_it(tmp_path, capsys, dialect, body, line,
                                                              word):
    rc, out = _run(tmp_path, body, dialect)
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert len(err.splitlines()) == 1 and f"p.nc:{line}: {word} has no decimal point" in err, err
    assert "0.001 mm" in err
    # the machine setting that would read it in whole units, the controller's own
    assert ("Setting 162 (Default To Float)" if dialect == "haas" else "parameter 3401#0 DPI") in err


def test_inch_names_the_inch_increment(tmp_path, capsys):
    prog = tmp_path / "p.nc"
    prog.write_text("%\nO1000\nG20 G90\nG00 X0. Y0. Z1.\nG01 Y2 F10.\nM30\n%\n")
    model = str(_model(tmp_path, "xfyz", scale=0.1)[2])
    assert main(["compensate", "xfyz", model, str(prog), "-o", str(tmp_path / "o.nc"), "--quiet"]) == 2
    assert "Y2 has no decimal point" in capsys.readouterr().err


@pytest.mark.parametrize("machine, text, word", [
    ("xfyz", "G21 G90 G17\nG0 X0 Y0 Z5.\nG68 X0 Y0 R30\nG1 X10. F100.\nG69\n", "R30"),  # 0.030 deg
    ("cafxyz", "G21 G90\nG0 X0 Y0 Z50. A0 C0\nG1 C90 F1000.\n", "C90"),              # 0.090 deg
])
def test_an_angle_names_the_degree_increment(tmp_path, machine, text, word):
    """G68's rotation angle and a rotary axis word are angles: 0.001 deg without a point."""
    from mtcomp.errors import InputError
    from mtcomp.machine import load_machine
    from mtcomp.toolpaths import read_program
    p = tmp_path / "p.nc"
    p.write_text("O1000\n" + text + "M30\n")
    with pytest.raises(InputError) as exc:
        read_program(p, load_machine(machine), dialect="fanuc")
    assert exc.value.line == 4 and f"{word} has no decimal point" in exc.value.message
    assert "(0.001 deg)" in exc.value.message, exc.value.message


def test_zero_dwell_repeat_count_and_codes_stay_accepted(tmp_path):
    body = ("G00 X0 Y0 Z25.\nG04 X2\nG04 P500\nG01 Z-1. F300.\nG81 X10. Y10. Z-5. R2. K3 F100.\n"
            "G80\nG05.1 Q1\nG05.1 Q0\nT2 M06\nG43 H2 Z25.\n")
    rc, out = _run(tmp_path, body, "fanuc")
    assert rc == 0 and out.exists()


def test_linuxcnc_and_grbl_read_whole_millimetres(tmp_path):
    # LinuxCNC and grbl read X60 as 60 mm: nothing to refuse (the program names no Fanuc)
    prog, out = tmp_path / "p.ngc", tmp_path / "o.ngc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z25\nG1 X60 F1200\nM2\n")
    model = str(_model(tmp_path, "xfyz", scale=0.1)[2])
    for dialect in ("linuxcnc", "grbl"):
        assert main(["compensate", "xfyz", model, str(prog), "-o", str(out), "--quiet",
                     "--dialect", dialect]) == 0
        moved = re.search(r"G1 X([0-9.]+)", out.read_text())
        assert moved and abs(float(moved.group(1)) - 60.0) < 0.01


def test_the_compiled_reader_hands_whole_words_to_python_on_fanuc_only(tmp_path, monkeypatch):
    """The compiled reader sends a line with `X7` to Python (which refuses it) on fanuc and haas
    only: elsewhere such lines stay on the compiled path, which reads them as whole units."""
    from mtcomp.errors import InputError
    from mtcomp.machine import load_machine
    from mtcomp.toolpaths import _fast, iter_segment_chunks
    from mtcomp.toolpaths.modal import ModalState
    if not _fast.available():
        pytest.skip("no C compiler: the compiled G-code path is not available")
    read_in_python = []
    block = ModalState.block

    def spy(self, line, text):
        read_in_python.append(line)
        return block(self, line, text)
    monkeypatch.setattr(ModalState, "block", spy)
    p = tmp_path / "p.nc"
    p.write_text("G21 G90\nG0 X0 Y0 Z0\n" + "".join(f"G1 X{k} F100\n" for k in range(1, 31)) + "M30\n")
    xfyz = load_machine("xfyz")
    for dialect in ("fanuc", "haas"):
        with pytest.raises(InputError, match="X1 has no decimal point") as exc:
            list(iter_segment_chunks(p, xfyz, dialect=dialect))
        assert exc.value.line == 3
    read_in_python.clear()
    ends = np.vstack([c.end for c in iter_segment_chunks(p, xfyz, dialect="linuxcnc")])
    np.testing.assert_allclose(ends[-1], [30.0, 0.0, 0.0], rtol=0, atol=0)
    assert not set(read_in_python) & set(range(4, 33)), read_in_python


# An F word without a point. A Haas reads it as its Setting 77 (Scale Integer F) says: F1200 is
# 1.2 mm/min at the default (0.001 mm/min a unit), 1200 mm/min at INTEGER (Haas mill operator's
# manual, Settings). A Fanuc reads a feed per minute in whole mm/min (F1200: 1200 mm/min), but an
# inverse time (G93) in thousandths unless parameter 3401#0 (DPI) is set (Fanuc Series 16/18-MC
# operator's manual, B-62764EN/01, feed functions: "F1 0.001"). The feed enters the corrections
# through a model's feed terms (FOFF_X: um per m/min): 1200 mm/min and 1.2 mm/min give offsets
# 1000 times apart.
FEED_BODY = "G00 X0. Y0. Z25.\nG01 X60. F1200\nG01 Y20.\n"


def _feed_model(tmp_path):
    from mtcomp.models import FeedOffset, save_model
    from test_export_formats import random_model
    fm = random_model("xfyz", (FeedOffset("X"),), 3, 0.0, None)
    fm.params.set_file_value("FOFF_X", 2.0)
    path = tmp_path / "feed.json"
    save_model(path, fm)
    return path


def _compensate(tmp_path, body, model, dialect, head=HEAD):
    prog, out = tmp_path / "p.nc", tmp_path / "out.nc"
    prog.write_text(head + body + TAIL)
    rc = main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--dialect", dialect])
    return rc, out


def test_a_haas_f_without_a_point_is_refused_where_the_model_uses_the_feed(tmp_path, capsys,
                                                                            reader_path):
    rc, out = _compensate(tmp_path, FEED_BODY, _feed_model(tmp_path), "haas")
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert len(err.splitlines()) == 1 and "p.nc:6: F1200 has no decimal point" in err, err
    # both readings by hand: 1200 * 0.001 mm/min at the default, 1200 mm/min at INTEGER
    assert "Setting 77 (Scale Integer F)" in err and "1.2 mm/min at its default" in err
    assert "1200 mm/min at INTEGER" in err and "feed terms (feed_dependent_offset:X)" in err
    # with a point it is read and corrected as 1200 mm/min
    rc, out = _compensate(tmp_path, FEED_BODY.replace("F1200", "F1200."), _feed_model(tmp_path),
                          "haas")
    assert rc == 0 and out.exists(), capsys.readouterr().err


def test_a_haas_f_without_a_point_is_read_in_whole_units_where_nothing_uses_it(tmp_path, capsys,
                                                                               reader_path):
    model = _model(tmp_path, "xfyz", scale=0.1)[2]
    rc, out = _compensate(tmp_path, FEED_BODY, model, "haas")
    said = capsys.readouterr().out
    assert rc == 0 and out.exists()
    assert "note: F words without a decimal point (first F1200, line 6) read in whole mm/min" in said
    assert "Setting 77" in said
    # the same program with F1200. is written alike (the feed is not among what is corrected)
    text = out.read_text()
    rc, out = _compensate(tmp_path, FEED_BODY.replace("F1200", "F1200."), model, "haas")
    assert rc == 0 and out.read_text() == text.replace("F1200", "F1200.")


def test_a_fanuc_feed_per_minute_without_a_point_is_whole_mm_per_min(tmp_path, capsys):
    from mtcomp.machine import load_machine
    from mtcomp.toolpaths import read_program
    prog = tmp_path / "p.nc"
    prog.write_text(HEAD + FEED_BODY + TAIL)
    blocks = read_program(prog, load_machine("xfyz"), dialect="fanuc").blocks
    assert [b.feed for b in blocks if b.line == 6] == [1200.0]
    rc, out = _compensate(tmp_path, FEED_BODY, _feed_model(tmp_path), "fanuc")
    assert rc == 0 and "F words without" not in capsys.readouterr().out


@pytest.mark.parametrize("dialect", ["fanuc", "haas"])
def test_an_inverse_time_f_without_a_point_is_refused(tmp_path, capsys, dialect):
    """Under G93 mtcomp writes each split block's F anew from the one read: F6 read as 6 (1/min) but
    run as 0.006 would be written as pieces' F12. and faster, run 2000 times faster."""
    body = "G00 X0. Y0. Z25.\nG93 G01 X60. F6\nG94\n"
    rc, out = _compensate(tmp_path, body, _model(tmp_path, "xfyz", scale=0.1)[2], dialect)
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert len(err.splitlines()) == 1 and "p.nc:6: F6 has no decimal point under G93" in err, err
    assert "0.006 1/min" in err


#: fixed-format numbers: Siemens NX's post for a Monarch VMC with a GE control writes
#: `N0040G00X0019685Y-0008937`, 1.9685 in and -0.8937 in placed by the format (the G-code corpus,
#: nxpost_Monarch_VMC_GE_sample.ptp)
FIXED = "G20 G90 G17\nG0 X1. Y1. Z.5\n"


@pytest.mark.parametrize("body, word", [
    ("G1 X0019685 Y1. F10.\n", "X0019685"),           # the GE post's format: read as 19685 before
    ("G1 Y-05 F10.\n", "Y-05"),
    ("G2 X3. Y1. I01 J0\n", "I01"),                   # an arc's centre
])
def test_a_fixed_format_number_is_refused_where_nothing_names_the_controller(
        tmp_path, capsys, reader_path, body, word):
    """Nothing names the controller: X0019685 is 19685 in whole units, 1.9685 in a 3.4 format, and
    the corrected word would be written with a point; both readers refuse it at its line."""
    prog, out = tmp_path / "p.nc", tmp_path / "out.nc"
    prog.write_text(FIXED + body + "M30\n")
    rc = main(["compensate", "xfyz", str(_model(tmp_path, "xfyz", scale=0.1)[2]), str(prog), "-o",
               str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert len(err.splitlines()) == 1 and f"p.nc:3: {word} is a fixed-format number" in err, err


def test_a_fixed_format_number_is_whole_units_on_linuxcnc(tmp_path, reader_path):
    """LinuxCNC reads `X015` as 15 (G-code reference, "Numbers"): accepted when the program is said
    to be LinuxCNC's, the word corrected by less than 0.01 in."""
    prog, out = tmp_path / "p.nc", tmp_path / "out.nc"
    prog.write_text(FIXED + "G1 X015 F10.\nM30\n")
    rc = main(["compensate", "xfyz", str(_model(tmp_path, "xfyz", scale=0.1)[2]), str(prog), "-o",
               str(out), "--quiet", "--dialect", "linuxcnc"])
    assert rc == 0
    x = [float(m) for m in re.findall(r"^G1 X([-\d.]+)", out.read_text(), re.M)]
    assert len(x) == 1 and x[0] == pytest.approx(15.0, abs=0.01)


def _calculator_machine(tmp_path, value="true"):
    """The built-in xfyz with ``calculator_input`` (a top-level key, before its tables)."""
    from mtcomp import machine as machine_module
    from pathlib import Path
    text = (Path(machine_module.__file__).parent / "machines" / "xfyz.toml").read_text()
    path = tmp_path / "xfyz-calculator.toml"
    path.write_text(f"calculator_input = {value}\n" + text)
    return path


def test_a_machine_set_to_calculator_input_reads_whole_units(tmp_path, capsys):
    """Fanuc parameter 3401#0 DPI = 1 ("calculator-type"), said in the machine file: X60 is 60 mm,
    so the program is compensated as the same program with X60. is (its words written with a point,
    which the control reads alike); under G93 a Fanuc's F6 is then 6 1/min. A Haas's F stays
    Setting 77's (Setting 162 is about dimension words): refused under G93 there."""
    machine = str(_calculator_machine(tmp_path))
    model = str(_model(tmp_path, "xfyz", scale=0.1)[2])
    body = ("G00 X0. Y0. Z25.\nG01 X60 F1200.\nG02 X80 Y20 I10 J10\nG81 X10 Y10 Z-20 R2 Q5 F100.\n"
            "G80\nG93 G01 X5 F6\nG94\n")
    written, said = {}, {}
    for name, text in (("whole", body), ("pointed", re.sub(r"([XYZIJRQ]-?\d+)(?![\d.])", r"\1.",
                                                          body))):
        prog, out = tmp_path / f"{name}.nc", tmp_path / f"{name}.out.nc"
        prog.write_text(HEAD + text + TAIL)
        assert main(["compensate", machine, model, str(prog), "-o", str(out), "--dialect",
                     "fanuc"]) == 0, capsys.readouterr().err
        written[name] = out.read_text().splitlines()
        said[name] = capsys.readouterr().out
    assert "note: dimension words without a decimal point (first X60, line 6) read in whole " \
        "units" in said["whole"] and "parameter 3401#0 DPI" in said["whole"]
    assert "dimension words without" not in said["pointed"]
    whole, pointed = written["whole"], written["pointed"]
    moved = [k for k, line in enumerate(whole) if line != pointed[k]]
    # only lines whose words the correction rewrote may differ, and then by the points alone
    def pointless(line):
        return re.sub(r"(\d)\.(?!\d)", r"\1", line)
    for k in moved:
        assert pointless(whole[k]) == pointless(pointed[k]), (whole[k], pointed[k])
    moved_to = re.match(r"G01 X(\d+\.\d*) ", whole[5])        # 60 mm, not 0.060 mm
    assert moved_to and float(moved_to.group(1)) == pytest.approx(60.0, abs=0.01), whole[5]
    # without the setting the first such word is refused, naming the machine file's key
    prog = tmp_path / "whole.nc"
    assert main(["compensate", "xfyz", model, str(prog), "-o", str(tmp_path / "o.nc"), "--dialect",
                 "fanuc"]) == 2
    assert "whole.nc:6: X60 has no decimal point" in capsys.readouterr().err
    prog.write_text(HEAD + "G00 X0. Y0. Z25.\nG93 G01 X60. F6\nG94\n" + TAIL)
    assert main(["compensate", machine, model, str(prog), "-o", str(tmp_path / "o.nc"),
                 "--dialect", "haas"]) == 2
    assert "F6 has no decimal point under G93" in capsys.readouterr().err


def test_calculator_input_is_true_or_false_and_kept_with_the_model(tmp_path):
    from mtcomp.errors import InputError
    from mtcomp.machine import load_machine, machine_from_dict
    m = load_machine(_calculator_machine(tmp_path))
    assert m.calculator_input and machine_from_dict(m.to_dict()).calculator_input
    assert not load_machine("xfyz").calculator_input
    with pytest.raises(InputError, match="calculator_input must be true or false, got 1"):
        load_machine(_calculator_machine(tmp_path, "1"))
