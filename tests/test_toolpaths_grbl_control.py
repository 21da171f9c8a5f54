"""Control characters in a grbl program: grbl 1.1 throws away every byte up to the blank as it
reads a line (grbl's protocol.c; CR and LF end the line), so a line holding one runs as if it
were absent, and the written program keeps the byte where it was (the controller drops it again).
Ctrl-X (0x18) is grbl's soft reset (serial.c) and DEL (0x7F) is not dropped (its parser answers
it with an error): both refused, as every control character is on the other dialects, in one
line naming the line and the byte. Positions and written words are derived by hand with the
correction dX = 10 um + 0.002 Z, dY = 20 um + 0.003 Z, dZ = 30 um (mm)."""
import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks
from mtcomp.toolpaths.gcode import write_corrected
from test_compensate_cli import _model, _run
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)

XFYZ = load_machine("xfyz")
#: 0x01 at a line's end and at its start, 0x1F between two words, 0x7F inside a comment
PROGRAM = (b"G21 G90\n"
           b"G0 X1 Y2 Z3\x01\n"
           b"G1 X4\x1f Y5 F100\n"
           b"G1 Z-1 (note\x7f)\n"
           b"\x01G1 X6\n"
           b"M30\n")


def _chunks(path, dialect):
    return list(iter_segment_chunks(path, XFYZ, dialect=dialect))


def _written(tmp_path, data: bytes, dialect="grbl") -> bytes:
    src, out = tmp_path / "in.gcode", tmp_path / "out.gcode"
    src.write_bytes(data)
    corrections = []
    for c in _chunks(src, dialect):
        z = c.end[:, 2:3]
        delta = np.hstack([0.010 + 0.002 * z, 0.020 + 0.003 * z, np.full_like(z, 0.030)])
        corrections.append((c, c.end + delta, np.ones(len(c), np.int64)))
    write_corrected(src, out, XFYZ, corrections, dialect=dialect)
    return out.read_bytes()


def test_grbl_reads_the_line_without_its_control_characters(tmp_path, mode):
    src = tmp_path / "in.gcode"
    src.write_bytes(PROGRAM)
    chunks = _chunks(src, "grbl")
    ends = np.vstack([c.end for c in chunks])
    lines = np.concatenate([c.line for c in chunks])
    # by hand: G0 to (1, 2, 3), G1 to (4, 5, 3), to (4, 5, -1), to (6, 5, -1)
    np.testing.assert_allclose(ends[:, :3], [[1, 2, 3], [4, 5, 3], [4, 5, -1], [6, 5, -1]],
                               rtol=0, atol=1e-12)
    assert lines.tolist() == [2, 3, 4, 5]


def test_grbl_output_keeps_the_control_characters_in_place(tmp_path, mode):
    out = _written(tmp_path, PROGRAM)
    # X 1 + 0.010 + 0.006, Y 2 + 0.020 + 0.009, Z 3 + 0.030; at Z -1: X 4 + 0.010 - 0.002, Y 5 +
    # 0.020 - 0.003 (Z alone moves: the X and Y to write change), X 6 + 0.010 - 0.002
    assert out.split(b"\n") == [
        b"G21 G90",
        b"G0 X1.0160 Y2.0290 Z3.0300\x01",
        b"G1 X4.0160\x1f Y5.0290 F100",
        b"G1 Z-0.9700 X4.0080 Y5.0170 (note\x7f)",
        b"\x01G1 X6.0080",
        b"M30",
        b""]


def test_grbl_output_is_the_output_of_the_program_without_them(tmp_path, mode):
    # a second formulation: the same program without its control characters is written with the
    # same words; the output with them is that output, each byte where the source had it
    plain = PROGRAM.replace(b"\x01", b"").replace(b"\x1f", b"")
    out = _written(tmp_path, PROGRAM)
    assert out.replace(b"\x01", b"").replace(b"\x1f", b"") == _written(tmp_path, plain)
    assert out.count(b"\x01") == 2 and out.count(b"\x1f") == 1 and out.count(b"\x7f") == 1


def test_grbl_drops_a_control_character_inside_a_word(tmp_path, mode):
    # grbl reads X\x016 as X6; the corrected word is written anew, without the byte
    out = _written(tmp_path, b"G21 G90\nG0 X1 Y2 Z0\nG1 X\x016 F100\n")
    assert out.split(b"\n")[2] == b"G1 X6.0100 F100"


@pytest.mark.parametrize("data, where, words", [
    (b"G21\nG0 X1 Y2 Z3\x7f\n", "in.gcode:2:", "control character 0x7F (DEL) outside a comment"),
    (b"G21\nG0 X1\x18 Y2 Z3\n", "in.gcode:2:", "control character 0x18 (Ctrl-X) in a line"),
])
def test_grbl_refuses_what_it_does_not_drop(tmp_path, mode, data, where, words):
    src = tmp_path / "in.gcode"
    src.write_bytes(data)
    with pytest.raises(InputError) as exc:
        _chunks(src, "grbl")
    assert where in str(exc.value) and words in str(exc.value), str(exc.value)


@pytest.mark.parametrize("dialect", ["linuxcnc", "generic", "fanuc"])
def test_other_dialects_refuse_a_control_character(tmp_path, mode, dialect):
    src = tmp_path / "in.gcode"
    src.write_bytes(PROGRAM)
    with pytest.raises(InputError) as exc:
        _chunks(src, dialect)
    assert "in.gcode:2:" in str(exc.value), str(exc.value)
    assert "control character 0x01 (grbl drops it" in str(exc.value), str(exc.value)


def test_compensate_under_linuxcnc_refuses_in_one_line(tmp_path, capsys):
    _machine, _fitted, model = _model(tmp_path, "xfyz")
    src, out = tmp_path / "in.gcode", tmp_path / "out.gcode"
    src.write_bytes(PROGRAM)
    code, _out, err = _run(["compensate", "xfyz", str(model), str(src), "-o", str(out),
                            "--dialect", "linuxcnc"], capsys)
    assert code == 2 and not out.exists()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert "in.gcode:2:" in lines[0] and "control character 0x01" in lines[0], lines[0]
    # and under grbl the same program is compensated
    code, _out, err = _run(["compensate", "xfyz", str(model), str(src), "-o", str(out),
                            "--dialect", "grbl", "--quiet"], capsys)
    assert code == 0, err
    assert out.read_bytes().count(b"\x01") == 2
