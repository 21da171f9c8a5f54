"""The W quill of horizontal boring mills (mtcomp/toolpaths/quill.py): W words pass through as
written, the model is evaluated with the tip at Z + W and the tool longer by -W, and a block whose
W is not known is not corrected. Checked by hand against single error terms (docs/conventions.md):
a pitch eps(y) of the Y carriage moves the tip by dy = -eps (z_tip - L0), a pitch eps(z_ram) of the
ram by dy = +eps L (L the arm from the gauge point to the tip), so at one Y and one Z word the
corrections with and without an extended quill stand in the ratio of those arms."""
import csv
from dataclasses import replace
from importlib import resources

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.toolpaths.gcode import iter_segment_chunks
from test_gcode_corpus import _machine_file as corpus_machine, _model_file
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)

#: the built-in xfyz with a W quill declared (a boring mill's machine file: docs/machines.md)
XFYZ = replace(load_machine("xfyz"), quill=True)
L0 = XFYZ.tool_length          # 100 mm
Z, W = 20.0, -30.0
#: the quill at 0 (line 4) and extended by 30 mm (line 6), at the same Y and Z words
PROGRAM = ("G21 G90 G54\nG0 X10. Y50. Z20. W0.\nG1 X12. F100.\nG0 W-30.\nG1 X10. F100.\n"
           "G1 X11.\nM30\n")


def _machine_file(tmp_path, quill=True):
    """The built-in xfyz's file, with ``quill = true`` added to its [axes.Z] table."""
    text = resources.files("mtcomp").joinpath("machines/xfyz.toml").read_text()
    if quill:
        text = text.replace("[axes.Z]\n", "[axes.Z]\nquill = true\n")
    path = tmp_path / "machine.toml"
    path.write_text(text)
    return path


def _run(tmp_path, text, param="EAY_1", dialect="fanuc", quill=True):
    """compensate's exit status on the program ``text`` (a model of one term, ``param``)."""
    model = ErrorModel(load_machine("xfyz").with_basis("polynomial"))
    fitted = FittedModel.zero(model)
    fitted.params.values[[s.name for s in model.param_specs].index(param)] = 1000.0e-6
    save_model(tmp_path / "m.json", fitted)
    prog = tmp_path / "p.nc"
    prog.write_text(text)
    return main(["compensate", str(_machine_file(tmp_path, quill)), str(tmp_path / "m.json"),
                 str(prog), "-o", str(tmp_path / "o.nc"), "--report", str(tmp_path / "r.csv"),
                 "--method", "pinv", "--dialect", dialect, "--quiet", "--max-step-um", "1000",
                 "--max-correction-um", "1000"])


def _compensate(tmp_path, text, param, dialect="fanuc"):
    assert _run(tmp_path, text, param, dialect) == 0
    with open(tmp_path / "r.csv") as f:
        rows = {int(r["line"]): r for r in csv.DictReader(f)}
    return rows, (tmp_path / "o.nc").read_text()


@pytest.mark.parametrize("param, ratio", [
    ("EAY_1", (Z + W - L0) / (Z - L0)),     # the tip's Z (the Y carriage's Abbe arm) is Z + W
    ("EAZ_1", (L0 - W) / L0),               # the ram's arm to the tip is the tool plus the quill
])
def test_the_correction_is_the_models_error_where_the_quill_puts_the_tip(tmp_path, param, ratio):
    rows, out = _compensate(tmp_path, PROGRAM, param)
    plain, extended = float(rows[3]["cy_um"]), float(rows[5]["cy_um"])
    assert abs(plain) > 0.1                 # the term is felt (um)
    np.testing.assert_allclose(extended / plain, ratio, rtol=2e-3)
    # W words as written, none added, the W-only line byte for byte
    src, dst = PROGRAM.splitlines(), out.splitlines()
    assert dst[3] == src[3]
    assert [ln.count("W") for ln in dst] == [ln.count("W") for ln in src]


def test_a_block_whose_quill_is_not_known_is_not_corrected(tmp_path):
    # G53 W0 sends the quill to a machine position; a tool change may move it: Z of the tip is not
    # known until the program names W again (line 5 and 9 not corrected, 7 and 11 corrected)
    text = ("G21 G90\nG0 X10. Y50. Z20.\nW-30.\nG53 G0 W0.\nG1 X12. F100.\nW-10.\n"
            "G1 X10.\nT2 M6\nG1 X12. Z20.\nW-10.\nG1 X10.\nM30\n")
    rows, out = _compensate(tmp_path, text, "EAY_1")
    assert [int(rows[k]["corrected"]) for k in (5, 7, 9, 11)] == [0, 1, 0, 1]
    assert rows[5]["unknown_axes"] == "Z" and rows[9]["unknown_axes"] == "Z"
    # G28 W0 sends the quill alone home: X and Y stay known, Z of the tip is not
    rows, _out = _compensate(tmp_path, "G21 G90\nG0 X10. Y50. Z20. W0.\nG1 X12. F100.\n"
                             "G91 G28 W0.\nG90 G1 X10.\nW-5.\nG1 X12.\nM30\n", "EAY_1")
    assert [rows[k]["unknown_axes"] for k in (3, 5, 7)] == ["", "Z", ""]
    # a block moving W with X, Y or Z is not corrected either: its tip moves with the quill
    rows, _out = _compensate(tmp_path, "G21 G90\nG0 X10. Y50. Z20. W0.\nG1 X12. W-5. F100.\n"
                             "G1 X10.\nM30\n", "EAY_1")
    assert [int(rows[k]["corrected"]) for k in (3, 4)] == [0, 1]


#: a W where the quill's travel is the controller's own rule; on haas a W at all (a Haas mill has
#: no W; on its lathes W is Z given incrementally)
REFUSED = [
    ("fanuc", "G2 X20. W-2. I5. J0 F100.", "W in a drilling cycle or arc"),
    ("fanuc", "G81 X20. Z-2. R1. W-2. F100.", "W in a drilling cycle"),
    ("haas", "G1 W-1. F100.", "incremental X and Z"),
]


@pytest.mark.parametrize("dialect, block, message", REFUSED)
def test_w_is_refused_where_its_meaning_is_not_known(tmp_path, dialect, block, message):
    (tmp_path / "p.nc").write_text(f"G21 G90\nG0 X10. Y0 Z5.\n{block}\nM30\n")
    with pytest.raises(InputError, match=message) as exc:
        list(iter_segment_chunks(tmp_path / "p.nc", XFYZ, dialect=dialect))
    assert exc.value.line == 3


#: a Fanuc lathe's or mill-turn's W (Z given incrementally, G-code system A): two W-10 moves leave
#: Z at -15, where a quill would leave the tip's Z at 5 - 20
LATHE = "O0001\nG21 G90 G18\nG0 X10. Y0 Z5.\nG1 W-10. F100.\nW-10.\nG1 X20.\nM30\n"


def test_w_is_a_quill_only_where_the_machine_file_declares_one(tmp_path, capsys):
    # without quill = true W keeps the lathe's meaning on fanuc: refused in one line, nothing
    # written (exit 2); with it, the program is read
    assert _run(tmp_path, LATHE, quill=False) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "p.nc:4:" in err and "axis word W on fanuc (on its lathes U and W are incremental X " \
        "and Z) is not supported" in err and "quill = true" in err
    assert not (tmp_path / "o.nc").exists()
    assert _run(tmp_path, LATHE, quill=True) == 0
    # the machine file: quill on Z only, true or false, kept in the model's machine
    machine = load_machine(_machine_file(tmp_path))
    assert machine.quill and machine.to_dict()["axes"]["Z"]["quill"] is True
    plain = load_machine("xfyz")
    assert not plain.quill and "quill" not in plain.to_dict()["axes"]["Z"]
    for table, value, message in (("X", "true", "unknown key 'quill'"),
                                  ("Z", '"yes"', "quill must be true or false")):
        path = tmp_path / "bad.toml"
        path.write_text(_machine_file(tmp_path, quill=False).read_text().replace(
            f"[axes.{table}]\n", f"[axes.{table}]\nquill = {value}\n"))
        with pytest.raises(InputError, match=message):
            load_machine(path)


@pytest.mark.parametrize("quill", [True, False])
def test_a_spline_with_w_is_refused(tmp_path, quill):
    # a G5 spline is X and Y only: its W would move the tip's Z unseen by the blocks after it
    (tmp_path / "p.nc").write_text("G21 G90\nG0 X0 Y0 Z5 W0\nG1 Z1 F100\n"
                                   "G5 X10 Y0 I1 J1 P1 Q1 W-20\nG1 X20 Y5\nM30\n")
    machine = XFYZ if quill else load_machine("xfyz")
    with pytest.raises(InputError, match=r"G5 \(cubic spline\) with W: its axes are X and") as exc:
        list(iter_segment_chunks(tmp_path / "p.nc", machine, dialect="generic"))
    assert exc.value.line == 4


@pytest.mark.parametrize("home", ["G28", "G30"])
def test_a_home_move_of_every_axis_homes_the_quill_before_its_first_w(tmp_path, home):
    # G28 / G30 alone sends W home too, even before the program names W: the tip's Z is not known
    # (line 5 not corrected, Z unknown) until a W word (line 7 corrected)
    rows, _out = _compensate(tmp_path, f"G21 G90\nG0 X10. Y50. Z20.\n{home}\nG0 X10. Y50. Z20.\n"
                             "G1 X12. F100.\nW-10.\nG1 X10.\nM30\n", "EAY_1")
    assert [int(rows[k]["corrected"]) for k in (5, 7)] == [0, 1]
    assert rows[5]["unknown_axes"] == "Z"


#: the quill's place lost before line 5: G28 W0 homes it (line 4), or a tool change does (the
#: builder's macro may move it), before the program's first W word too
LOST = {"G28 W": "G0 X10. Y50. Z20. W0.\nG1 X12. F100.\nG91 G28 W0.\nG90 ",
        "M6 before W": "G0 X10. Y50. Z20.\nG1 X12. F100.\nT2 M6\n"}


@pytest.mark.parametrize("lost", sorted(LOST))
def test_no_z_word_where_the_tips_z_is_not_known(tmp_path, mode, lost):
    """Lines 5 and 6 (after the quill's place is lost) are not corrected and report Z unknown; the
    output gets no Z word there but the one line 6 names, as written (the output's Z stays where
    line 3 left it: nominal 20 plus its correction, as the controller keeps an axis a line does not
    name); line 8, after W-5., is corrected again. A large random model (the corpus test's) so that
    line 3's Z correction is not zero."""
    text = "G21 G90\n" + LOST[lost] + "G1 X10.\nG1 X14. Z15.\nW-5.\nG1 X12.\nM30\n"
    machine = corpus_machine(tmp_path, "XFYZ", quill=True)
    (tmp_path / "p.nc").write_text(text)
    assert main(["compensate", str(machine), str(_model_file(tmp_path, machine)),
                 str(tmp_path / "p.nc"), "-o", str(tmp_path / "o.nc"), "--report",
                 str(tmp_path / "r.csv"), "--dialect", "fanuc", "--quiet"]) == 0
    with open(tmp_path / "r.csv") as f:
        rows = {int(r["line"]): r for r in csv.DictReader(f)}
    out = (tmp_path / "o.nc").read_text().splitlines()
    assert abs(float(rows[3]["cz_um"])) >= 0.1          # line 3 leaves Z off nominal
    assert [(rows[k]["corrected"], rows[k]["unknown_axes"]) for k in (5, 6, 8)] == [
        ("0", "Z"), ("0", "Z"), ("1", "")]
    assert "Z" not in out[4], out
    assert out[5] == text.splitlines()[5], out
    assert "Z" in out[7], out
