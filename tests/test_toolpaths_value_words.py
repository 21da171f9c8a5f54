"""A value word no code of its block uses (``G1 Y120. Q5``): refused, naming the word and the line,
where the controller refuses it, accepted where it does not.

The oracle is each controller's own rule, written here from its source: LinuxCNC's
``interp_check.cc`` (``check_other_codes``: a Q needs G73, G83, G10, G64, M19, M61, M66-M68 or a
user M code in its block, a P G4, G10, G64, G82, G84, G86, G88, G89 or an M code that takes it,
an L a drilling cycle, G10, G41/G42 or M66, an H G43, a D G41/G42 or G96), grbl 1.1's ``gcode.c``
(an unused value word is error 36; D, E, H and Q are no grbl words: error 20), and Fanuc, which
keeps P, Q and R as modal data of its canned cycles (no alarm)."""
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks, write_corrected

XFYZ = load_machine("xfyz")
HEAD = "G21 G90 G17\nG0 X0 Y0 Z10.\n"


def _read(tmp_path, text, dialect):
    p = tmp_path / "in.nc"
    p.write_text(text)
    return p, [c for c in iter_segment_chunks(p, XFYZ, dialect=dialect)]


@pytest.mark.parametrize("dialect", ["linuxcnc", "generic"])
def test_a_q_word_on_a_g1_is_refused_on_rs274ngc(tmp_path, reader_path, dialect):
    # the lab's typo: a plain G1 line (the compiled scanner took it whole) with a Q word
    p = tmp_path / "in.nc"
    p.write_text(HEAD + "G1 X20. F600\nG1 Y120. Q5\nG1 X-20.\nM2\n")
    with pytest.raises(InputError, match=r"Q word in a G1 block: no code of the block uses it "
                                         r"\(Q goes with G73 G83 ") as exc:
        list(iter_segment_chunks(p, XFYZ, dialect=dialect))
    assert exc.value.line == 4 and f"{p}:4: " in str(exc.value)
    out = tmp_path / "out.nc"
    with pytest.raises(InputError, match="Q word"):
        write_corrected(p, out, XFYZ, None, dialect=dialect)
    assert not out.exists()


@pytest.mark.parametrize("dialect", ["fanuc", "haas"])
def test_a_q_word_on_a_g1_passes_where_the_control_keeps_it(tmp_path, reader_path, dialect):
    # Fanuc keeps Q as the canned cycles' modal data: no alarm; the line passes with its Q
    text = HEAD + "G1 X20. F600\nG1 Y120. Q5\nM30\n"
    p, chunks = _read(tmp_path, text, dialect)
    assert [int(x) for c in chunks for x in c.line] == [2, 3, 4]
    out = tmp_path / "out.nc"
    write_corrected(p, out, XFYZ, None, dialect=dialect)
    assert out.read_text() == text


@pytest.mark.parametrize("line, moves", [
    ("G83 X1 Y1 Z-1 R1 Q0.5 F100", True), ("G73 X1 Y1 Z-1 R1 Q0.5 F100", True),
    ("G82 X1 Y1 Z-1 R1 P0.5 F100", True), ("G90 G81 X1 Y1 Z-1 R1 L2 F100", True),
    ("G4 P1.5", False), ("G10 L2 P1 X0", False), ("G64 P0.01 Q0.01", False),
    ("M66 P0 L3 Q5", False), ("M67 E0 Q20", False), ("M101 P1 Q2", False),
    ("G43 H1 Z5", True), ("G41 D1 G1 X1 F100", True), ("G2 X2 Y0 I1 J0 F100", True),
    ("G1 X1 F100 S2000 M3 T1", True),
])
def test_words_a_code_of_their_block_takes_pass_on_linuxcnc(tmp_path, reader_path, line,
                                                            moves):
    _p, chunks = _read(tmp_path, HEAD + line + "\nM2\n", "linuxcnc")
    lines = {int(x) for c in chunks for x in c.line}
    assert lines == ({2, 3} if moves else {2})


@pytest.mark.parametrize("line, word", [
    ("G0 X1 P2", "P word in a G0 block"), ("G1 X1 L2 F100", "L word in a G1 block"),
    ("H1", "H word in a block without motion"), ("T1 M6 D1", "D word in a block without motion"),
    ("G81 X1 Y1 Z-1 R1 Q1 F100", "Q word in a G81 block"), ("G1 X1 E2 F100", "E word in a G1"),
    ("G81 X1 Y1 Z-1 R1 K2 F100", "K word in a G81 block"), ("G49 H0", "H word in a block"),
    ("M3 S1000 P5", "P word in a block without motion"),
])
def test_words_no_code_of_their_block_takes_are_refused_on_linuxcnc(tmp_path, reader_path, line,
                                                                    word):
    p = tmp_path / "in.nc"
    p.write_text(HEAD + line + "\nM2\n")
    with pytest.raises(InputError, match=word) as exc:
        list(iter_segment_chunks(p, XFYZ, dialect="linuxcnc"))
    assert exc.value.line == 3 and "LinuxCNC refuses such a block" in str(exc.value)


@pytest.mark.parametrize("line, moves", [
    ("G49 H0", False), ("G91 G98 G81 X5 Y0 Z-4 R-8 K2 F100", True),
    ("G98 G83 X5 Y5 Z-3 R2 I1 J0.2 K0.5 F100", True),
])
def test_a_program_naming_no_controller_keeps_the_words_mtcomp_reads_everywhere(
        tmp_path, reader_path, line, moves):
    # Centroid's and Fanuc's G49 H0, Fanuc's repeat count K, Haas' peck words I J K
    _p, chunks = _read(tmp_path, HEAD + line + "\nG90 G80\nM2\n", "generic")
    assert {int(x) for c in chunks for x in c.line} == ({2, 3} if moves else {2})


@pytest.mark.parametrize("line, ok", [
    ("G4 P1", True), ("G10 L2 P1 X0", True), ("G2 X2 Y0 I1 J0 F100", True),
    ("G1 X1 P1 F100", False), ("G2 X2 Y0 R1 I1 F100", False), ("G1 X1 Q1 F100", False),
])
def test_grbl_refuses_what_its_parser_does(tmp_path, reader_path, line, ok):
    text = HEAD + line + "\nM2\n"
    if ok:
        _read(tmp_path, text, "grbl")
        return
    p = tmp_path / "in.nc"
    p.write_text(text)
    with pytest.raises(InputError, match="error 36|error 20") as exc:
        list(iter_segment_chunks(p, XFYZ, dialect="grbl"))
    assert exc.value.line == 3


def test_compensate_refuses_it_in_one_line_and_writes_nothing(tmp_path, refused_on_xfyz):
    err = refused_on_xfyz("typo3.ngc", HEAD + "G1 X20. F600\nG1 Y120. Q5\nM2\n")
    assert f"{tmp_path / 'typo3.ngc'}:4: Q word in a G1 block" in err
