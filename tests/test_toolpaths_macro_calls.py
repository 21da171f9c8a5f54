"""Fanuc macro calls G65 (custom macro B, simple call) to a program in the same file, expanded where
they are called: the hand-derived positions of every block on both reader paths (the arguments
become the local variables #24 #25 #26 of X Y Z, the caller's #1 comes back after the return, an
L2 call repeats with the locals it left), the compensated program equal to the compensation of the
same program flattened by hand (a second formulation), and the refusals, each in one line naming
the line and the construct. Before, every G65 was refused ("G65 (macro call)"), with its macro in
the file or not."""
import numpy as np
import pytest

from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks
from mtcomp.toolpaths.source import open_program
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)
from test_toolpaths_subprograms import check_refused, compensated_lines

XFYZ = load_machine("xfyz")

#: a pocket macro called at two places, the second time twice (L2): its second pass goes 1 mm
#: deeper, from the #26 the first pass left (Haas mill operator's manual, G65: the arguments are
#: set on the first repetition only)
G65 = """%
O0001 (MAIN)
G90 G21 G17
G0 X0 Y0 Z5.
#1=7.
G65 P9010 X10. Y5. Z-1.
G1 X#1 F300
G65 P9010 X20. Y-5. Z-2. L2
G0 Z5.
M30
O9010 (POCKET)
G1 X#24 Y#25 F200
G1 Z#26
#26=#26-1.
G0 Z5.
M99
%
"""
G65_FLAT = """%
O0001 (MAIN)
G90 G21 G17
G0 X0 Y0 Z5.
G1 X10. Y5. F200
G1 Z-1.
G0 Z5.
G1 X7. F300
G1 X20. Y-5. F200
G1 Z-2.
G0 Z5.
G1 X20. Y-5. F200
G1 Z-3.
G0 Z5.
G0 Z5.
M30
%
"""
G65_ENDS = [[0, 0, 5], [10, 5, 5], [10, 5, -1], [10, 5, 5], [7, 5, 5], [20, -5, 5], [20, -5, -2],
            [20, -5, 5], [20, -5, 5], [20, -5, -3], [20, -5, 5], [20, -5, 5]]


def test_the_blocks_of_a_called_macro_come_where_it_is_called(tmp_path, mode):
    p = tmp_path / "p.nc"
    p.write_text(G65)
    for dialect in ("fanuc", None):          # O0001 names a Fanuc-type control
        with open_program(p, dialect) as src:
            ends = np.vstack([c.end for c in iter_segment_chunks(src, XFYZ)])
        np.testing.assert_allclose(ends, G65_ENDS, rtol=0, atol=1e-9)


def test_compensated_as_the_program_flattened_by_hand(tmp_path, capsys):
    written = compensated_lines(tmp_path, capsys, {"sub": G65, "flat": G65_FLAT})
    sub, flat = written["sub"], written["flat"]
    assert sub[2].startswith("(expanded by mtcomp from sub.nc for fanuc") and "macro calls" in sub[2]
    assert sub[3:-7] == flat[2:-1]
    assert sub[-7:] == G65.splitlines()[-7:]
    assert flat != G65_FLAT.splitlines()          # corrected


_MAIN = "O1\nG0 X0 Y0 Z5.\n"


@pytest.mark.parametrize("text, dialect, words", [
    # a machine's resident macro (a probing or chip-breaking cycle): its motion is not in the file
    (_MAIN + "G65 P8232 Z-3.93701 D1. S0.\nM30\n", "fanuc",
     ["p.nc:3:", "G65 P8232: no program O8232 in this file"]),
    (_MAIN + "G65 P2 I1. J1. I2.\nM30\nO2\nG1 X#4 F100\nM99\n", "fanuc",
     ["p.nc:3:", "G65 with I more than once"]),
    (_MAIN + "G65 P2 X1.\nM30\nO2\nG65 P2 X#24\nM99\n", "fanuc",
     ["p.nc:6:", "macro calls nested more than 4 deep"]),
    (_MAIN + "G65 X1.\nM30\n", "fanuc", ["p.nc:3:", "G65 without P"]),
    (_MAIN + "G1 X1. F100 G65 P2\nM30\nO2\nM99\n", "fanuc", ["p.nc:3:", "G65 with G more than once"]),
    (_MAIN + "G65 P2 X1.\nM30\nO2\nG1 X#1 F100\nM99\n", "fanuc", ["p.nc:6:", "#1 is read before"]),
    ("G0 X0 Y0 Z5\nG65 P2 X1.\nM30\n", None, ["p.nc:2:", "G65 (macro call", "--dialect fanuc"]),
    (_MAIN + "G66 P2 X1.\nG1 X2. F100\nG67\nM30\nO2\nM99\n", "fanuc", ["p.nc:3:", "G66"]),
])
def test_macro_calls_refused_in_one_line(tmp_path, capsys, text, dialect, words):
    check_refused(tmp_path, capsys, text, dialect, words)


@pytest.mark.parametrize("lines, calls", [
    (["G0 X1", "G65 P1000 X1.", "M30"], True), (["G0 X1", "g 065 p2", "M30"], True),
    (["G0 X1 (G65 P1000)", "M30"], False), (["G0 X1 ; G65", "M30"], False),
    (["G1 X1.65 Y65", "G165", "G65.1", "G0 X65"], False), (["N10G65P1X1."], True)])
def test_a_macro_call_is_found_in_any_block(tmp_path, lines, calls):
    """needs_expansion finds G65 outside comments in a Fanuc or Haas program, in whichever 64 kB
    block it lies; elsewhere it is no call (the reader refuses it)."""
    from mtcomp.toolpaths.dialect import needs_expansion
    filler = "G1 X1.2345 Y-2.3465 Z-3.4567\n" * 3000      # 87 kB, a '65' on every line
    for head in ("", filler):
        p = tmp_path / "p.nc"
        p.write_text(head + "\n".join(lines) + "\n")
        assert needs_expansion(p, macro_calls=True) is calls, (head[:5], lines)
        assert needs_expansion(p) is False
