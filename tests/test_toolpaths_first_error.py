"""The first error in program order is the one told: a move beyond the travel at one line and a bad
arc at the next are refused at the first (the reader hands out the rows before a bad line before
its error, so the planner's check of their travel comes first); so are a move beyond the travel
and an error in the program's code (O-words, parameters, Fanuc macros) at a later executed line:
the expansion keeps the lines executed before the error, and the readers raise it after them."""
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks

XFYZ = load_machine("xfyz")
#: the lab's typo4.ngc on xfyz (Y travel -300 .. 300 mm): line 5 goes to Y1200, line 6's arc
#: (centre 20 mm from its start, 1060 mm from its end) is one no controller accepts
TYPO = ("G21 G90 G17 G94\nG0 X-20. Y60. Z80.\nG1 Z40. F300\nG2 X20. Y60. I20. J0.\n"
        "G1 Y1200.\nG3 X20. Y140. I-20. J0.\nG1 X-20.\nM2\n")


def test_the_rows_before_a_bad_line_come_out_before_its_error(tmp_path, reader_path):
    p = tmp_path / "p.nc"
    p.write_text(TYPO)
    seen = []
    with pytest.raises(InputError, match="arc radius inconsistent") as exc:
        for chunk in iter_segment_chunks(p, XFYZ, chunk_size=1000):
            seen += [int(x) for x in chunk.line]
    assert exc.value.line == 6
    # the arc of line 4 is cut into chords, all with its line; line 5 is the last row
    assert sorted(set(seen)) == [2, 3, 4, 5] and seen[-1] == 5


def test_compensate_tells_the_move_beyond_the_travel_first(tmp_path, reader_path,
                                                           refused_on_xfyz):
    err = refused_on_xfyz("typo4.ngc", TYPO)
    assert f"{tmp_path / 'typo4.ngc'}:5: Y 1200.0000 mm is outside the travel of axis Y" in err


#: the same with code: line 5 goes to Y1200 through a parameter, line 6 reads one never set
#: (LinuxCNC: "named parameter used before it is set"), line 3 was executed twice by a loop
CODE = ("G21 G90 G17 G94\nG0 X-20. Y60. Z80.\n#<k> = 0\no1 while [#<k> LT 2]\n"
        "G1 Z[40 - #<k>] F300\n#<k> = [#<k> + 1]\no1 endwhile\n#<y> = 1200\nG1 Y#<y>\n"
        "G1 X[#<undefined> + 1]\nM2\n")


def test_a_travel_error_before_a_code_error_is_told_first(tmp_path, reader_path,
                                                          refused_on_xfyz):
    err = refused_on_xfyz("code.ngc", CODE)
    # named in the user's file (and the expansion: its comment, lines 2, 5, 5, then 9)
    # (and, no work offset given, that G54 was taken as 0)
    assert err.endswith(f"{tmp_path / 'code.ngc'}:9: Y 1200.0000 mm is outside the travel of axis "
                        "Y (-300 .. 300 mm) of machine carver800t-like (line 6 of the expanded "
                        "program), with work offset G54 taken as 0 (nobody gave it): give "
                        "--work-offset or --offsets")


def test_the_code_error_comes_after_the_rows_executed_before_it(tmp_path, reader_path):
    p = tmp_path / "code.ngc"
    p.write_text(CODE.replace("1200", "120"))
    seen = []
    with pytest.raises(InputError, match="used before it is set") as exc:
        for chunk in iter_segment_chunks(p, XFYZ, chunk_size=1000):
            seen += [int(x) for x in chunk.line]
    assert exc.value.path == str(p) and exc.value.line == 10
    # the rows are lines of the expansion: its comment, lines 2, 5 (twice), 9 of the source
    assert len(seen) == 4 and seen == sorted(seen)


@pytest.mark.parametrize("text", ["G21 G90\n#1 = [1 / 0]\nG0 X1\nM2\n",
                                  "G21 G90\no1 while [1]\nG0 X1\no1 endwhile\nM2\n"])
def test_an_error_with_nothing_executed_before_it_or_a_runaway_loop_is_told(tmp_path, text):
    from mtcomp.toolpaths.source import open_program
    p = tmp_path / "code.ngc"
    p.write_text(text)
    with pytest.raises(InputError) as exc:
        with open_program(p, max_steps=1000, max_lines=1000) as src:
            list(iter_segment_chunks(src, XFYZ))
    assert exc.value.line == 2

