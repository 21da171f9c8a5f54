"""Under cutter radius compensation (G41/G42) no block is split: the controller offsets the moves
as written, and a short entry move or a sliver of an arc makes it alarm (LinuxCNC: "Length of
cutter compensation entry move is not greater than the tool radius") or turn the tool centre by the
cutter's radius. Arcs there are kept whole, and compensate says how far they miss."""
import re

import pytest

from test_compensate_cli import _model, _run

CONTOUR = ("G21 G90 G17\nG0 X-180 Y-150 Z5\nG1 Z-2 F100\n{on}G1 X-150 Y-100 F300\nG1 X150\n"
           "G2 X150 Y100 I0 J100\nG1 X-150\n{off}G1 X-180 Y-150\nG0 Z5\nM2\n")


def _compensate(tmp_path, capsys, text, name):
    _, _, model = _model(tmp_path, "xfyz", seed=5, scale=20.0)
    p, out = tmp_path / f"{name}.ngc", tmp_path / f"{name}_out.ngc"
    p.write_text(text)
    code, o, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(out),
                         "--dialect", "linuxcnc", "--chord-tol-um", "0.5"], capsys)
    assert code == 0, err
    return out.read_text().splitlines(), o + err


def test_a_contour_under_cutter_compensation_keeps_its_blocks(tmp_path, capsys):
    plain, said_plain = _compensate(tmp_path, capsys, CONTOUR.format(on="", off=""), "plain")
    src = CONTOUR.format(on="G41\n", off="G40\n").splitlines()
    crc, said = _compensate(tmp_path, capsys, CONTOUR.format(on="G41\n", off="G40\n"), "crc")
    # the same model splits the plain contour (internal nodes, arcs in pieces) ...
    assert len(plain) > len(CONTOUR.format(on="", off="").splitlines())
    # ... and keeps every block of the compensated one: one output line per source line, each
    # holding the source's words in order (numbers corrected, an axis whose value changes added)
    assert len(crc) == len(src)
    for a, b in zip(src, crc):
        letters = re.sub(r"[^A-Z]", "", re.sub(r"[-\d.]+", "", a.upper()))
        got = iter(re.sub(r"[^A-Z]", "", re.sub(r"[-\d.]+", "", b.upper())))
        assert all(c in got for c in letters), (a, b)
    assert "0 internal nodes inserted" in said
    m = re.search(r"no block is split .*?(?:up to ([\d.]+) um)?$", said, re.M)
    assert m is not None, said
    assert crc[6].startswith("G2 X") and " I" in crc[6] and " J" in crc[6]


@pytest.mark.parametrize("on", ["G42 D1", "g41"])
def test_switching_on_in_the_move_itself_counts(tmp_path, capsys, on):
    text = ("G21 G90 G17\nG0 X-180 Y-150 Z5\nG1 Z-2 F100\n"
            f"G1 {on} X-150 Y-100 F300\nG1 X150\nG1 G40 X180 Y-150\nM2\n")
    crc, said = _compensate(tmp_path, capsys, text, "inline")
    assert len(crc) == len(text.splitlines())

