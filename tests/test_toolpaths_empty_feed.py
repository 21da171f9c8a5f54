"""An F word without a number (`G00 Z8.0000 F`: Estlcam 11 writes one on every rapid of its
programs for Marlin routers), on both reader paths: on the generic dialect kept byte for byte, the
feed in force unchanged (Marlin, src/gcode/parser.cpp GCodeParser::parse: a parameter letter
without a value is seen without one; src/gcode/gcode.cpp get_destination_from_command: G0/G1 set
the feed only from an F with a value), said once; refused where the controller refuses it
(LinuxCNC: bad number format; grbl 1.1: error 2) and by every named dialect; every other letter
without a number stays refused. The feeds expected are written out by hand; the old reader refused
every one of these programs ("word F without a valid number")."""
import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.toolpaths import iter_segment_chunks
from mtcomp.toolpaths.gcode import write_corrected
from mtcomp.toolpaths.source import open_program
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)

XFYZ = load_machine("xfyz")
PROGRAM = ("G21 G90 G94\nG00 X0.0000 Y0.0000 Z0.0000 F4000\nG00 Z8.0000 F\nG01 X10.0000 F500\n"
           "G00 Z5.0000 F\nG01 X20.0000 Y1.0000 F (kept)\nG00 F\nG01 Y2.0000 F\t;end\nM30\n")


def _written(tmp_path, text: str, dialect: str | None = None):
    """(the written lines, the rows' lines, feeds and end points, the notes) of a program written
    with every row corrected by dX = +10 um, dY = -20 um, dZ = +30 um."""
    src_path, out = tmp_path / "in.nc", tmp_path / "out.nc"
    src_path.write_text(text)
    with open_program(src_path, dialect) as src:
        chunks = list(iter_segment_chunks(src, XFYZ))
        delta = np.array([0.010, -0.020, 0.030])
        write_corrected(src, out, XFYZ, [(c, c.end + delta, np.ones(len(c), np.int64))
                                         for c in chunks])
        notes = list(src.notes)
    rows = (np.concatenate([c.line for c in chunks]), np.concatenate([c.feed for c in chunks]),
            np.vstack([c.end for c in chunks]))
    return out.read_text().splitlines(), rows, notes


@pytest.mark.parametrize("dialect", [None, "generic"])
def test_the_feed_in_force_stays_and_the_f_is_kept(tmp_path, mode, dialect):
    lines, (rows, feeds, ends), notes = _written(tmp_path, PROGRAM, dialect)
    assert rows.tolist() == [2, 3, 4, 5, 6, 8]          # line 7 (G00 F) moves nothing
    # by hand: rapids have no feed; F500 of line 4 stays through the empty F of lines 6 and 8
    np.testing.assert_array_equal(feeds, [np.nan, np.nan, 500.0, np.nan, 500.0, 500.0])
    np.testing.assert_allclose(ends[-1], [20, 2, 5], rtol=0, atol=1e-12)
    # only the corrected words change: each F is kept where it was written
    assert lines == ["G21 G90 G94", "G00 X0.0100 Y-0.0200 Z0.0300 F4000", "G00 Z8.0300 F",
                     "G01 X10.0100 F500", "G00 Z5.0300 F", "G01 X20.0100 Y0.9800 F (kept)",
                     "G00 F", "G01 Y1.9800 F\t;end", "M30"]
    said = [n for n in notes if "F word without a number" in n]
    assert len(said) == 1 and "line 3" in said[0] and "LinuxCNC and grbl refuse it" in said[0]


@pytest.mark.parametrize("dialect", ["linuxcnc", "grbl", "fanuc", "haas", "rrf"])
def test_the_controllers_that_refuse_it_refuse_it(tmp_path, mode, dialect):
    p = tmp_path / "p.nc"
    p.write_text(PROGRAM)
    with pytest.raises(InputError, match=r"p\.nc:3: word F without a valid number"):
        list(iter_segment_chunks(p, XFYZ, dialect=dialect))


@pytest.mark.parametrize("line, msg", [
    ("G01 X5 F500 F", "an F without a number and an F with one"),   # which F counts is not known
    ("G01 X5 FY1", "word F without a valid number"),                 # no blank after it
    ("G01 X5 F.", "word F without a valid number"),
    ("G01 X5 S", "word S without a valid number"),                   # any other letter
    ("G01 X", "word X without a valid number"),
])
def test_other_words_without_a_number_stay_refused(tmp_path, mode, line, msg):
    p = tmp_path / "p.nc"
    p.write_text("G21 G90\nG0 X0 Y0 Z0\n" + line + "\n")
    with pytest.raises(InputError, match=r"p\.nc:3: " + msg):
        list(iter_segment_chunks(p, XFYZ, dialect="generic"))


def test_the_command_line_says_it_once_and_refuses_it_named(tmp_path, capsys):
    model = tmp_path / "model.json"
    save_model(model, FittedModel.zero(ErrorModel(XFYZ.with_basis("polynomial"))))
    (tmp_path / "in.nc").write_text(PROGRAM)
    args = ["compensate", "xfyz", str(model), str(tmp_path / "in.nc"), "-o", str(tmp_path / "o.nc")]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert out.count("note: an F word without a number (first at line 3: 'G00 Z8.0000 F')") == 1
    # a zero model corrects nothing: the program is written as it was read
    assert (tmp_path / "o.nc").read_text() == PROGRAM
    for dialect in ("linuxcnc", "grbl"):
        (tmp_path / "o.nc").unlink(missing_ok=True)
        assert main(args + ["--dialect", dialect]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "in.nc:3: word F without a valid number" in err[0]
        assert not (tmp_path / "o.nc").exists()
