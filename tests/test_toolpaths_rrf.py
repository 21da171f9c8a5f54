"""RepRapFirmware programs (the rrf dialect) on both reader paths: quoted string parameters pass
through as written (doubled quotes, ';' and '(' inside them), the codes the firmware runs from its
own macro files and a T tool change leave every axis unknown (a move after them writes only the axes
it names), the work offsets the program set become the controller's, M5011's unstated turn is
taken as 0 and said once, detection. The written words are checked against a hand-made correction
that changes with Z (see _written), so a move of Z alone changes the X and Y to write."""
import math
import re

import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import _fast, iter_segment_chunks
from mtcomp.toolpaths.dialect import detect
from mtcomp.toolpaths.gcode import write_corrected
from mtcomp.toolpaths.reader import iter_blocks
from test_compensate_cli import _model, _run
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)

XFYZ = load_machine("xfyz")
STRINGS = ('M4000 P11 R15 S"Face Mill ""D30"" ; not a comment (nor this)"\n'
           'M291 P"x" R"y" S2 ; a comment with "a quote\n')


def _written(tmp_path, text: str, dialect: str | None = "rrf") -> list[str]:
    """The program written with every known axis corrected by dX = 10 um + 0.002 Z, dY = 20 um +
    0.003 Z, dZ = 30 um (mm)."""
    src, out = tmp_path / "in.gcode", tmp_path / "out.gcode"
    src.write_text(text)
    chunks = list(iter_segment_chunks(src, XFYZ, dialect=dialect))
    corrections = []
    for c in chunks:
        z = c.end[:, 2:3]
        delta = np.hstack([0.010 + 0.002 * z, 0.020 + 0.003 * z, np.full_like(z, 0.030)])
        corrections.append((c, c.end + delta, np.ones(len(c), np.int64)))
    write_corrected(src, out, XFYZ, corrections, dialect=dialect)
    return out.read_text().splitlines()


def _axes(line: str) -> set:
    return set(re.findall(r"([XYZ])-?\d", line.split(";")[0]))


def test_string_parameters_pass_through_as_written(tmp_path, mode):
    text = "G21 G90\n" + STRINGS + 'G0 X1 Y2 Z3\nG1 X4 F100 K"a;(b)"\n'
    out = _written(tmp_path, text)
    assert out[:3] == text.splitlines()[:3]          # byte for byte, quotes and all
    # the moves after them read as usual: by hand, X 1 + 0.010 + 0.006, Y 2 + 0.020 + 0.009; the
    # second keeps Z: Y's written value stays in force; its string stays as written
    assert out[3:] == ["G0 X1.0160 Y2.0290 Z3.0300", 'G1 X4.0160 F100 K"a;(b)"']


@pytest.mark.parametrize("dialect", ["generic", "fanuc"])
def test_a_quote_stays_refused_on_other_dialects(tmp_path, dialect):
    p = tmp_path / "p.gcode"
    p.write_text("G21\n" + STRINGS)
    with pytest.raises(InputError, match="word S without a valid number") as exc:
        list(iter_segment_chunks(p, XFYZ, dialect=dialect))
    assert exc.value.line == 2


@pytest.mark.parametrize("line3, message", [
    ('M117 "not closed ""', "quoted string not closed"),
    ("G6600 G1 X2", "G6600 .* and a move in one block")])
def test_refused_by_line(tmp_path, line3, message):
    p = tmp_path / "p.gcode"
    p.write_text(f"G21\nG0 X1 Y1 Z1\n{line3}\n")
    with pytest.raises(InputError, match=message) as exc:
        list(iter_segment_chunks(p, XFYZ, dialect="rrf"))
    assert exc.value.line == 3


@pytest.mark.parametrize("code", ["G6600", "G27", "M3.9 S18000", "M7000 P4000 V200", "T11",
                                  "M5011", "G6512 X10 Z-5", 'M98 P"probe.g"', "M6"])
def test_after_a_macro_a_move_writes_only_the_axes_it_names(tmp_path, mode, code):
    """X Y Z known, then a firmware macro (or tool change): the next move names Z only, so X and Y
    are not written, and a later move naming X Y writes them again. Without the macro line the same
    Z move gets X and Y written (their correction changes with Z): the check can fail."""
    body = "G21 G90\nG0 X10 Y20 Z5\n{}G1 Z-1 F100\nG1 X30 Y40\nG1 X35\n"
    out = _written(tmp_path, body.format(code + "\n"))
    assert out[2] == code
    assert out[3] == "G1 Z-0.9700 F100"
    assert out[4] == "G1 X30.0080 Y40.0170"
    assert out[5] == "G1 X35.0080"
    plain = _written(tmp_path, body.format(""))
    assert plain[2] == "G1 Z-0.9700 X10.0080 Y20.0170 F100"


def test_a_move_to_a_restore_point_passes_through_and_forgets_its_axes(tmp_path, mode):
    """G1 R1 X0 Y0 Z5 (RepRapFirmware: 5 mm above restore point 1, which a pause or G60 S1 saved,
    G90 or G91 alike): the line passes as written, X Y Z unknown afterwards, so the next move naming
    Z only writes Z, and X Y come back when named. An R with no axis moves nothing (the firmware
    restores only the axes named): X Y stay known."""
    out = _written(tmp_path, "G21 G90\nG0 X10 Y20 Z5\nG60 S1\nG1 R1 X0 Y0 Z5 F6000\n"
                   "G1 Z-1 F100\nG1 X30 Y40\nG1 R2 F300\nG1 Z2\n")
    assert out[3] == "G1 R1 X0 Y0 Z5 F6000"
    assert out[4] == "G1 Z-0.9700 F100"
    assert out[5] == "G1 X30.0080 Y40.0170"
    assert out[6] == "G1 R2 F300"
    assert out[7] == "G1 Z2.0300 X30.0140 Y40.0260"


@pytest.mark.parametrize("line3, dialect, message", [
    ("G1 R6 X0", "rrf", "restore points are 0 to 5"),
    ("G1 R1.5 X0", "rrf", "restore points are 0 to 5"),
    ("G1 X0 R1", "generic", "R word in a G1 block")])
def test_a_g1_r_rrf_does_not_take_is_refused(tmp_path, line3, dialect, message):
    p = tmp_path / "p.gcode"
    p.write_text(f"G21\nG0 X1 Y1 Z1\n{line3}\n")
    with pytest.raises(InputError, match=message) as exc:
        list(iter_segment_chunks(p, XFYZ, dialect=dialect))
    assert exc.value.line == 3


def test_the_summary_counts_the_restore_moves(tmp_path):
    from mtcomp._compensation_notes import passed_move_notes
    from mtcomp.toolpaths.source import open_program
    prog = tmp_path / "p.gcode"
    prog.write_text("G21 G90\nG0 X10 Y20 Z5\nG1 Z-1 F100\nG1 R1 Z5\nG1 Z-2\nG1 R1 X0 Y0\nM2\n")
    stats = {}
    with open_program(prog, "rrf") as src:
        write_corrected(src, tmp_path / "o.gcode", XFYZ, None, stats=stats)
        said = passed_move_notes(src, stats)
    assert said == ["2 motion lines passed through uncorrected, with no BLOCKS.csv row: 2 moves to "
                    "a RepRapFirmware restore point (G0/G1 R, first at line 4: the controller "
                    "saved it)"]


def test_a_t_word_alone_changes_nothing_on_other_dialects(tmp_path):
    out = _written(tmp_path, "G21 G90\nG0 X10 Y20 Z5\nT11\nG1 Z-1 F100\n", dialect="generic")
    assert _axes(out[3]) == {"X", "Y", "Z"}


def test_native_codes_keep_the_positions(tmp_path, mode):
    # M3 (spindle), M400 (wait), G4 (dwell), G60 (save position), G31 (probe settings) are the
    # firmware's own and move nothing: the Z move keeps X Y written
    out = _written(tmp_path, "G21 G90\nG0 X10 Y20 Z5\nM3 S1000\nM400\nG4 P100\nG60 S0\nG31 Z1\n"
                   "G1 Z-1 F100\n")
    assert out[2:7] == ["M3 S1000", "M400", "G4 P100", "G60 S0", "G31 Z1"]
    assert out[7] == "G1 Z-0.9700 X10.0080 Y20.0170 F100"


def test_a_probing_macro_makes_the_programmed_offsets_the_controllers(tmp_path):
    """G10 L2 sets G55's X; after G6600 (which probes the origin of the system in force) the
    offset is the controller's (nan: taken from the command line), every axis unknown."""
    p = tmp_path / "p.gcode"
    p.write_text("G21 G90\nG10 L2 P2 X100 Y0 Z0\nG55\nG0 X1 Y1 Z1\nG6600\nG0 X2 Y2 Z2\n")
    seen = {}
    for k, _raw, _b, state in iter_blocks(p, XFYZ, dialect="rrf"):
        seen[k] = (state.offsets.offset(1, 0), state.known.copy())
    assert seen[4][0] == 100.0 and seen[4][1].all()
    assert math.isnan(seen[5][0]) and not seen[5][1].any()
    assert seen[6][1].all()


def test_the_bad_command_line_passes_through(tmp_path, mode):
    out = _written(tmp_path, "G21 G90\nG0 X10 Y20 Z5\n...\nG1 Z-1 F100\n")
    assert out[2] == "..."
    assert out[3] == "G1 Z-0.9700 X10.0080 Y20.0170 F100"        # nothing moved: X Y known


@pytest.mark.parametrize("text", [
    "(RepRapFirmware)\nG21 G90\n" + STRINGS + "G0 X10 Y20 Z5\nG6600\nG1 Z-1 F100\nG1 X30 Y40\n"
    "G2 X40 Y30 I10 J0\nT3\nG0 X1 Y1 Z1\n",
    # from the first line on: the compiled scanner would take the plain move and M3.9 itself
    "G0 X10 Y20 Z5\nM3.9 S100\nG1 Z-1 F100\n"], ids=["strings", "first-line"])
def test_both_reader_paths_write_the_same(tmp_path, monkeypatch, text):
    compiled = _written(tmp_path, text, dialect="rrf")
    monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
    python = _written(tmp_path, text, dialect="rrf")
    assert python == compiled
    assert "G1 Z-0.9700 F100" in python            # after the macro only Z is written


@pytest.mark.parametrize("text, line", [
    ('G21\nG0 X1\nM4005 V"v0.3.0"\n', 3),
    ("(Post Processor: MillenniumOS v0.3.0)\nG21\n", 1),
    ("; generated for RepRapFirmware\nG21\n", 1),
    ("(for RRF.)\nG21\n", 1),
])
def test_detection(tmp_path, text, line):
    p = tmp_path / "p.gcode"
    p.write_text(text)
    d, why = detect(p)
    assert d.name == "rrf" and why.startswith(f"detected from line {line}:")


def test_rotation_compensation_is_taken_as_no_turn_and_said_once(tmp_path, capsys):
    """M5011 (twice) writes the same corrections as another macro in its place (the turn taken as
    0); the note, once, gives the figure for 1 degree: pi/180 of the correction's size."""
    _machine, _fitted, model = _model(tmp_path, "xfyz", seed=8)
    body = ("G21 G90\nG55\nG6600\n{m}\nG0 X-50 Y-40 Z20\nG1 Z-5 F800\nX60\nG56\nG6600\n{m}\n"
            "G0 X10 Y10 Z5\nG1 Z-1 F100\nY30\n")
    outs, stdouts = [], []
    for name, m in (("rot", "M5011"), ("other", "M7000 P4000 V200")):
        prog, out = tmp_path / f"{name}.gcode", tmp_path / f"{name}.out.gcode"
        prog.write_text(body.format(m=m))
        code, stdout, err = _run(["compensate", "xfyz", str(model), str(prog), "-o", str(out),
                                  "--dialect", "rrf"], capsys)
        assert code == 0, err
        outs.append(out.read_text().splitlines())
        stdouts.append(stdout)
    rot, other = outs
    assert [a for a, b in zip(rot, other) if a != b] == ["M5011", "M5011"]
    assert rot[5] != "G1 Z-5 F800"                      # corrected
    notes = [n for n in stdouts[0].splitlines() if "M5011" in n]
    assert len(notes) == 1 and "line 4" in notes[0]
    assert f"1 degree: {100 * math.pi / 180:.2f} % of its size" in notes[0]
    assert not any("M5011" in n for n in stdouts[1].splitlines())


def test_a_line_across_the_block_read_in_a_python_only_mode(tmp_path, monkeypatch):
    """Under G93 (inverse time) the compiled scanner hands every line to Python; a line cut by the
    end of a block read (100 bytes here) is read whole on both paths, reading and writing (it was
    read cut: 'unexpected character')."""
    if not _fast.available():
        pytest.skip("no C compiler: the compiled G-code path is not available")
    text = "G21 G90\nG0 X0 Y0 Z0\nG93\n" + "".join(f"G1 X{k}.125 Y{k}.25 Z-1 F10\n"
                                                   for k in range(1, 60))
    monkeypatch.setattr(_fast, "_BLOCK", 100)
    compiled = _written(tmp_path, text, dialect="generic")
    monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
    assert compiled == _written(tmp_path, text, dialect="generic")
    assert compiled[-1] == "G1 X59.1330 Y59.2670 Z-0.9700 F10"
