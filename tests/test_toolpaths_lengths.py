"""The tool length the error model is given after G43 H0, G49 and an H on its own, per dialect
(docs/toolpaths.md, "Tool length offsets"): where the controller's offset becomes 0 (Fanuc's and
Haas' H00, RS274/NGC's H0, G49 on LinuxCNC, Fanuc, Haas and RS274/NGC) the point programmed is
the spindle's gauge point, a tool of length 0; LinuxCNC's G43 H0 takes the tool in the spindle;
grbl's G49 cancels only its dynamic offset. Expected lengths are the ones the program and the
command line state (H1 = 80 mm; nan: none stated, the machine's tool_length_mm)."""
import math

import numpy as np
import pytest

from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks
from mtcomp.toolpaths.offsets import ProgramSetup
from mtcomp.toolpaths.source import open_program

XFYZ = load_machine("xfyz")
H1 = 80.0
NAN = math.nan


def _lengths(tmp_path, text, dialect, name="p.nc"):
    """{line: (tool length of its row (mm, nan: the machine's), Z known on it)} of a program."""
    p = tmp_path / name
    p.write_text(text)
    out = {}
    with open_program(p, dialect) as src:
        setup = ProgramSetup(XFYZ, tool_lengths={1: H1})
        for chunk in iter_segment_chunks(src, XFYZ):
            placed, _off = setup.apply(chunk, src)
            for line, length, known in zip(chunk.line.tolist(), placed.tool_length.tolist(),
                                           chunk.known[:, 2].tolist()):
                out[line] = (length, known)
    return out


def _same(got, want):
    assert got.keys() == want.keys(), (got, want)
    for line, (length, known) in want.items():
        assert (math.isnan(length) and math.isnan(got[line][0])) or got[line][0] == length, \
            (line, got[line], want[line])
        assert got[line][1] == known, (line, got[line], want[line])


# G43 H1, then G43 H0, then G49 (each makes Z unknown until the next Z word)
G43_H0 = ("G21 G90 G54\nT1 M6\nG0 X10. Y10.\nG0 G43 H1 Z50.\nG1 X20. F500\nG43 H0\nG1 X25.\n"
          "G0 Z60.\nG1 X30.\nG49\nG0 Z70.\nG1 X40.\nM30\n")


@pytest.mark.parametrize("dialect, h0", [("fanuc", 0.0), ("haas", 0.0), ("generic", 0.0),
                                         ("linuxcnc", H1)])
def test_g43_h0_and_g49_per_dialect(tmp_path, reader_path, dialect, h0):
    """H0 is an offset of 0 (Fanuc, Haas, RS274/NGC), on LinuxCNC the tool in the spindle (T1);
    G49 cancels the offset on all four."""
    _same(_lengths(tmp_path, G43_H0, dialect),
          {3: (NAN, False), 4: (H1, True), 5: (H1, True), 7: (h0, False), 8: (h0, True),
           9: (h0, True), 11: (0.0, True), 12: (0.0, True)})


@pytest.mark.parametrize("dialect", ["linuxcnc", "generic", "fanuc"])
def test_a_g49_before_any_offset_keeps_the_machines_tool_length(tmp_path, dialect):
    """The safe-start line G17 G21 G40 G49 G80 G90 of a program that never applies an offset (a
    router's, its Z touched off with the tool): the tip, the machine file's length, as before."""
    text = "G17 G21 G40 G49 G80 G90\nG0 X10. Y10. Z50.\nG1 Z-1. F500\nG1 X20.\nM30\n"
    _same(_lengths(tmp_path, text, dialect), {2: (NAN, True), 3: (NAN, True), 4: (NAN, True)})


def test_grbl_g49_keeps_the_machines_tool_length(tmp_path, reader_path):
    """grbl's G49 cancels its dynamic offset (G43.1), relative to the tool the machine was zeroed
    with: the machine file's tool length stays."""
    text = "G21 G90\nG0 X10. Y10. Z50.\nG1 X20. F500\nG49\nG0 Z60.\nG1 X30.\nM30\n"
    _same(_lengths(tmp_path, text, "grbl"), {2: (NAN, True), 3: (NAN, True), 5: (NAN, True),
                                             6: (NAN, True)})


# an H on its own under G43 (Fanuc and Haas change the offset number), then under G49 (nothing)
LONE_H = ("%\nO1000\nN1 G90 G54 G0 X10. Y10.\nN2 G43 H1 Z50.\nN3 G1 X20. F500\nN4 H0\n"
          "N5 G1 X25.\nN6 G0 Z60.\nN7 G1 X30.\nN8 G49\nN9 H1\nN10 G0 Z70.\nN11 X40.\nN12 M30\n%\n")


@pytest.mark.parametrize("dialect", ["fanuc", "haas"])
def test_an_h_on_its_own_under_g43_changes_the_offset(tmp_path, reader_path, dialect):
    """N4 H0 under G43: offset 0 from there on, and Z unknown until N6 names it (the controller's Z
    in the program's frame moves by the tool length); N9 H1 under G49 changes nothing."""
    _same(_lengths(tmp_path, LONE_H, dialect),
          {3: (NAN, False), 4: (H1, True), 5: (H1, True), 7: (0.0, False), 8: (0.0, True),
           9: (0.0, True), 12: (0.0, True), 13: (0.0, True)})


def test_fanuc_keeps_g43_after_h0_and_takes_the_next_h(tmp_path, reader_path):
    """Fanuc: H0 is offset number 0 under G43, which stays in force, so a later H1 on its own
    applies H1's length again (Z unknown until named); on a Haas H00 cancels the compensation, so
    the same H1 changes nothing there."""
    text = ("%\nO1000\nN1 G90 G54 G0 X10. Y10.\nN2 G43 H1 Z50.\nN3 H0\nN4 G0 Z55.\nN5 H1\n"
            "N6 G1 X20. F500\nN7 G0 Z60.\nN8 M30\n%\n")
    fanuc = _lengths(tmp_path, text, "fanuc")
    haas = _lengths(tmp_path, text, "haas")
    assert fanuc[6] == (0.0, True) and haas[6] == (0.0, True)       # N4, after N3 H0
    assert fanuc[8] == (H1, False) and fanuc[9] == (H1, True)        # N6, N7, after N5 H1
    assert haas[8] == (0.0, True) and haas[9] == (0.0, True)


@pytest.mark.parametrize("dialect", ["linuxcnc", "generic", "grbl"])
def test_an_h_on_its_own_stays_refused_where_the_controller_refuses_it(tmp_path, dialect,
                                                                       refused_on_xfyz):
    err = refused_on_xfyz("p.nc", LONE_H.replace("%\nO1000\n", "").replace("N12 M30\n%\n",
                                                                           "N12 M30\n"))
    assert ":4: H word in a block without motion" in err


def test_the_model_is_evaluated_at_the_gauge_point_after_h0(tmp_path, capsys):
    """End to end: a block after G43 H0 is planned as the same block under a tool of length 0 given
    on the command line (the deviation before correction, BLOCKS.csv), not at H1's 80 mm."""
    import csv
    from mtcomp.cli import main
    from mtcomp.models import save_model
    from test_export_formats import random_model
    fm = random_model("xfyz", (), 3, 0.0, None)
    fm.params.set_file_value("EAZ_1", 500.0)        # an angular error of Z: an Abbe arm of L
    model = tmp_path / "m.json"
    save_model(model, fm)

    def ey(text, *flags):
        (tmp_path / "p.nc").write_text(text)
        assert main(["compensate", "xfyz", str(model), str(tmp_path / "p.nc"), "-o",
                     str(tmp_path / "o.nc"), "--report", str(tmp_path / "b.csv"), "--quiet",
                     "--dialect", "fanuc", "--tool-length", f"H1={H1:g}", *flags]) == 0
        with open(tmp_path / "b.csv", newline="") as f:
            return {int(r["line"]): float(r["ey_before_um"]) for r in csv.DictReader(f)
                    if r["ey_before_um"]}
    capsys.readouterr()
    h0 = ey("G21 G90 G54\nG0 X10. Y10.\nG0 G43 H0 Z-50.\nG1 X20. F500\nM30\n")
    zero = ey("G21 G90 G54\nG0 X10. Y10.\nG0 G43 H2 Z-50.\nG1 X20. F500\nM30\n",
              "--tool-length", "H2=0")
    h1 = ey("G21 G90 G54\nG0 X10. Y10.\nG0 G43 H1 Z-50.\nG1 X20. F500\nM30\n")
    assert abs(h1[4] - zero[4]) > 1.5, (h1, zero)       # the tool length matters here
    np.testing.assert_allclose([h0[3], h0[4]], [zero[3], zero[4]], rtol=0, atol=1e-9)


@pytest.mark.parametrize("dialect", ["linuxcnc", "generic", "grbl"])
def test_g43_1_words_are_the_dynamic_offset_not_a_move(tmp_path, dialect):
    """``G43.1 Z-3.245`` (LinuxCNC, grbl: a dynamic tool length offset) moves nothing: its Z is the
    offset (LinuxCNC G-code reference, G43.1; grbl v1.1 commands). The line is no block, and Z is
    unknown until the program names it again (read as a move to Z-3.245, the next traverse was
    written with that Z: a plunge of the offset's size and more)."""
    text = "G21 G90\nG0 X0 Y0 Z15\nG43.1 Z-3.245\nG0 X50 Y50\nG0 Z5\nG1 X60 F300\nM2\n"
    got = _lengths(tmp_path, text, dialect)
    assert sorted(got) == [2, 4, 5, 6]
    assert [got[k][1] for k in (2, 4, 5, 6)] == [True, False, True, True]


def test_g43_1_with_a_motion_code_and_axis_words_is_refused(refused_on_xfyz):
    """Both codes use the axis words: LinuxCNC refuses the block ("Cannot use two G codes that
    both use axis values"), and so does mtcomp."""
    err = refused_on_xfyz("p.nc", "G21 G90\nG0 X0 Y0 Z15\nG0 G43.1 Z-3.245\nM2\n")
    assert "p.nc:3: G43.1 and motion G0 in one block" in err
