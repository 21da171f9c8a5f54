"""Subprograms in the same file (Fanuc M98 / M99, Haas' local M97), expanded where they are called:
the hand-derived positions of every block on both reader paths, the compensated program equal to
the compensation of the same program flattened by hand (a second formulation), and the refusals,
each in one line naming the line and the construct. Before, a Haas M97 passed through as an
unknown M code: its subprogram's motion was missed and the next block got a Y word that moved the
machine back to where it stood before the call."""
import numpy as np
import pytest

from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks
from mtcomp.toolpaths.source import open_program
from test_compensate_cli import _model, _run
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)

XFYZ = load_machine("xfyz")

FANUC = """%
O0001 (MAIN)
G90 G21 G17
G0 X0 Y0 Z5.
G1 Z-1. F200
M98 P00021000
G1 X40. F300
M98 P1000
G0 Z5.
M30
O1000 (STEP)
G91 G1 X10. Y5. F300
G90
M99
%
"""
#: the same program as the controller runs it, flattened by hand: the subprogram twice, then once
FANUC_FLAT = """%
O0001 (MAIN)
G90 G21 G17
G0 X0 Y0 Z5.
G1 Z-1. F200
G91 G1 X10. Y5. F300
G90
G91 G1 X10. Y5. F300
G90
G1 X40. F300
G91 G1 X10. Y5. F300
G90
G0 Z5.
M30
%
"""
FANUC_ENDS = [[0, 0, 5], [0, 0, -1], [10, 5, -1], [20, 10, -1], [40, 10, -1], [50, 15, -1],
              [50, 15, 5]]

HAAS = """O01000 (HAAS)
G90 G21 G17
G0 X0 Y0 Z5.
M97 P100 L2
G1 X20. F100
M30
N100 G91 G1 Y30. F100
G90
M99
"""
HAAS_ENDS = [[0, 0, 5], [0, 30, 5], [0, 60, 5], [20, 60, 5]]
#: a second program in the file holds the block N100 the first one's M97 names: not its own
HAAS_OTHER = """O01000 (HAAS)
G0 X0 Y0 Z5.
M97 P100
M30
O02000
N100 G1 Y30. F100
M99
"""


def _ends(path, dialect):
    with open_program(path, dialect) as src:
        return np.vstack([c.end for c in iter_segment_chunks(src, XFYZ)])


@pytest.mark.parametrize("text, dialect, ends", [(FANUC, "fanuc", FANUC_ENDS),
                                                  (HAAS, "haas", HAAS_ENDS)])
def test_the_blocks_of_a_called_subprogram_come_where_it_is_called(tmp_path, mode, text, dialect,
                                                                   ends):
    p = tmp_path / "p.nc"
    p.write_text(text)
    np.testing.assert_allclose(_ends(p, dialect), ends, rtol=0, atol=1e-9)


def compensated_lines(tmp_path, capsys, programs: dict) -> dict:
    """name -> the lines of the program compensated as a Fanuc's (one model for all)."""
    _, _, model = _model(tmp_path, "xfyz", seed=5, scale=3.0)
    written = {}
    for name, text in programs.items():
        p, out = tmp_path / f"{name}.nc", tmp_path / f"{name}.out.nc"
        p.write_text(text)
        code, _o, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(out), "--quiet",
                              "--dialect", "fanuc"], capsys)
        assert code == 0, err
        written[name] = out.read_text().splitlines()
    return written


def test_compensated_as_the_program_flattened_by_hand(tmp_path, capsys):
    written = compensated_lines(tmp_path, capsys, {"sub": FANUC, "flat": FANUC_FLAT})
    sub, flat = written["sub"], written["flat"]
    # the expansion says so right after the tape's opening % and the program number line (a
    # Fanuc or Haas takes the number from the line after the %; a job shop worried that a comment
    # between them upsets the loader); then the hand-flattened program's output, and what follows
    # its M30 as it is in the file (the subprogram, the tape's end %)
    assert sub[:2] == ["%", "O0001 (MAIN)"] and flat[:2] == ["%", "O0001 (MAIN)"]
    assert sub[2].startswith("(expanded by mtcomp from sub.nc for fanuc")
    assert sub[3:-5] == flat[2:-1]
    assert sub[-5:] == ["O1000 (STEP)", "G91 G1 X10. Y5. F300", "G90", "M99", "%"]
    # and the corrections are there: the corrected ends differ from the source's
    assert flat != FANUC_FLAT.splitlines()


@pytest.mark.parametrize("text, dialect, words", [
    ("O1\nG0 X0 Y0 Z5.\nM98 P2000\nM30\n", "fanuc", ["p.nc:3:", "no program O2000 in this file"]),
    ("O1\nG0 X0 Y0 Z5.\nM98 P2\nM30\nO2\nG1 X5. F100\nM99 P10\n", "fanuc",
     ["p.nc:7:", "M99 P"]),
    ("O1\nG0 X0 Y0 Z5.\nG1 X3. F100 M98 P2\nM30\nO2\nG1 X5. F100\nM99\n", "fanuc",
     ["p.nc:3:", "M98 with other words on its line (F, G, X)"]),
    ("O1\nG0 X0 Y0 Z5.\nM98 P2\nM30\nO2\nG1 X5. F100\nM98 P2\nM99\n", "fanuc",
     ["p.nc:7:", "nested more than 10 deep"]),
    ("O1\nG0 X0 Y0 Z5.\nM98 P2\nM30\nO2\nG1 X5. F100\nO3\nG1 X6.\nM99\n", "fanuc",
     ["p.nc:7:", "without its M99"]),
    ("G0 X0 Y0 Z5.\nM97 P100\nM30\nN100 G1 X5. F100\nM99\n", "haas", None),
    ("G0 X0 Y0 Z5.\nM97 P200\nM30\nN100 G1 X5. F100\nM99\n", "haas", ["p.nc:2:", "no block N200"]),
    (HAAS_OTHER, "haas", ["p.nc:3:", "no block N100 in this program"]),
    ("G0 X0 Y0 Z5.\nM97 P100\nM30\nN100 G1 X5. F100\nM99\n", "fanuc", ["p.nc:2:", "M97 (Haas'"]),
    ("G0 X0 Y0 Z5.\nM97 P100\nM30\nN100 G1 X5. F100\nM99\n", None, ["p.nc:2:", "M97 (Haas'"]),
    ("G0 X0 Y0 Z5\nM98 P100\nM30\n", "linuxcnc", ["p.nc:2:", "M98 (subprogram call"]),
])
def test_calls_refused_in_one_line(tmp_path, capsys, text, dialect, words):
    check_refused(tmp_path, capsys, text, dialect, words)


def check_refused(tmp_path, capsys, text, dialect, words):
    """The program is refused in one line holding ``words`` (None: accepted), nothing written."""
    _, _, model = _model(tmp_path, "xfyz", seed=5)
    p, out = tmp_path / "p.nc", tmp_path / "out.nc"
    p.write_text(text)
    args = ["compensate", "xfyz", str(model), str(p), "-o", str(out), "--quiet"]
    code, _o, err = _run(args + (["--dialect", dialect] if dialect else []), capsys)
    if words is None:            # the accepted case beside the refused ones
        assert code == 0, err
        return
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert all(w in lines[0] for w in words), lines[0]
    assert not out.exists()


@pytest.mark.parametrize("code", ["G150 P100 Q0.5", "G47 P0", "G22 X5", "G241", "G200", "G60 X5",
                                  "G50 X0 Z0", "G64.7"])
def test_a_g_code_mtcomp_does_not_follow_is_refused(tmp_path, capsys, code):
    """Haas' pocket (G150) and engraving (G47) cycles, Fanuc's stroke limit (G22 X5: the X is a
    limit, not a move) and codes no reader knows were passed as if they changed nothing: the next
    block could then get a word for a position the machine never had. Refused, naming the code."""
    _, _, model = _model(tmp_path, "xfyz", seed=5)
    p, out = tmp_path / "p.nc", tmp_path / "out.nc"
    p.write_text(f"G90 G17 G21\nG0 X0 Y0 Z5.\n{code}\nG1 Y10. F100\nM30\n")
    code_, _o, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(out), "--quiet",
                           "--dialect", "haas"], capsys)
    lines = err.strip().splitlines()
    assert code_ == 2 and len(lines) == 1 and "p.nc:3:" in lines[0], err
    assert code.split()[0] in lines[0] and "not a code mtcomp follows" in lines[0], lines[0]
    assert not out.exists()


@pytest.mark.parametrize("dialect", ["linuxcnc", "fanuc", "generic"])
def test_haas_work_systems_are_refused_on_other_controllers(tmp_path, capsys, dialect):
    """G110-G129 are Haas' additional work systems; elsewhere G122 is no code at all (a typo of G1 or
    G2): refused, naming it, rather than read as a change of work system."""
    _, _, model = _model(tmp_path, "xfyz", seed=5)
    p, out = tmp_path / "p.nc", tmp_path / "out.nc"
    p.write_text("G90 G17 G21\nG0 X0 Y0 Z5.\nG122 X5. Y3.\nM30\n")
    code_, _o, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(out), "--quiet",
                           "--dialect", dialect], capsys)
    lines = err.strip().splitlines()
    assert code_ == 2 and len(lines) == 1 and "p.nc:3: G122 is not a code" in lines[0], err
    assert "--dialect haas" in lines[0] and not out.exists()


@pytest.mark.parametrize("line, why", [("G1 X1O.5 Y2 F500", "typed for a zero"),
                                       ("G1 X10.5 O1", "typed for a zero"),
                                       ("T1O1 M6", "after the tool word T1, a tool offset")])
def test_an_o_word_inside_a_line_is_refused(tmp_path, capsys, line, why):
    """A letter O typed for a zero (X1O.5): the line was read as X1 and the O.5 kept beside the
    corrected X. A program number opens its line (O0001 stays accepted). After a tool word (a
    DeVlieg post's T1O1) the message says what it may be."""
    _, _, model = _model(tmp_path, "xfyz", seed=5)
    p, out = tmp_path / "p.nc", tmp_path / "out.nc"
    p.write_text(f"O0001 (ok)\nG90 G17 G21\nG0 X0 Y0 Z5.\n{line}\nM30\n")
    code_, _o, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(out), "--quiet"],
                          capsys)
    lines = err.strip().splitlines()
    assert code_ == 2 and len(lines) == 1 and "p.nc:4: word O" in lines[0], err
    assert "inside a line" in lines[0] and why in lines[0] and not out.exists()


@pytest.mark.parametrize("code", ["G154 P1", "G110"])
def test_a_haas_work_system_change_forgets_the_positions(tmp_path, capsys, code):
    """After a change to one of Haas' additional work systems the next block names X only: Y and Z
    are not known in the new system, so the block is neither corrected nor given Y or Z words."""
    _, _, model = _model(tmp_path, "xfyz", seed=5, scale=3.0)
    p, out = tmp_path / "p.nc", tmp_path / "out.nc"
    p.write_text(f"G90 G17 G21\nG0 X0 Y0 Z5.\n{code}\nG1 X10. F100\nM30\n")
    code_, _o, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(out), "--quiet",
                           "--dialect", "haas"], capsys)
    assert code_ == 0, err
    assert out.read_text().splitlines()[3] == "G1 X10. F100"


@pytest.mark.parametrize("lines, calls", [
    (["G0 X1", "M98 P1000", "M30"], True), (["G0 X1", "m097 p2", "M30"], True),
    (["G0 X1 (M98 P1000)", "M30"], False), (["G0 X1 ; M98", "M30"], False),
    (["M980", "M9.8", "M3 S1000", "M9"], False), (["G1 X1 M98P1"], True),
    (["(a comment)", "mm98", "M 98 P1"], True)])
def test_a_subprogram_call_is_found_in_any_block(tmp_path, lines, calls):
    """needs_expansion finds M98/M97 outside comments, in whichever 64 kB block it lies (the call
    placed after enough plain lines that it falls in the second block, across the boundary)."""
    from mtcomp.toolpaths.dialect import needs_expansion
    filler = "G1 X1.2345 Y-2.3456 Z-3.4567\n" * 3000      # 87 kB
    for head in ("", filler):
        p = tmp_path / "p.nc"
        p.write_text(head + "\n".join(lines) + "\n")
        assert needs_expansion(p) is calls, (head[:5], lines)
