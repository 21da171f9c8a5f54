"""The command examples the user docs print (a ```` ``` ```` block with ``$ mtcomp ...`` lines and the
output under each) are run here, on the inputs the page describes, and every quoted line must be
what the command prints today: the same words, and every number within its last quoted digit (or
1 %); times (``1.1 s``) are not compared. A ``...`` line stands for lines the page leaves out.

The inputs are made here as the pages describe them (a model whose X scale is off by 40 um per
metre, a square contour, three drilled holes), or read from the real laser runs (which skip, saying
so, when the shared data folder is absent). A page's example that this file does not know fails
the test, so a new example cannot drift unseen."""
from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from real_data import ISO230_2
from test_viz_holes import CYCLE as HOLES
from test_viz_inplane import SQUARE

DOCS = Path(__file__).resolve().parents[1] / "docs"
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
_TIME = re.compile(r"[-+]?\d+(?:\.\d*)?(?= s\b)")


def _exx_inputs(tmp: Path) -> None:
    """MODEL.json: the X scale off by 40 um per metre (EXX_1 = 40); square.nc and holes.nc."""
    machine = load_machine("xfyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine))
    fitted.params.set_file_value("EXX_1", 40.0)
    save_model(tmp / "MODEL.json", fitted)
    (tmp / "square.nc").write_text(SQUARE)
    (tmp / "holes.nc").write_text(HOLES)


def _laser_inputs(tmp: Path) -> None:
    """Two real positioning runs (X and Y of one stage), as the pages name them."""
    for name in ("ess_b02_x.csv", "ess_b02_y.csv"):
        src = ISO230_2 / name
        if not src.is_file():
            pytest.skip(f"real ISO 230-2 runs not found ({src}): the shared data folder is absent")
        shutil.copy(src, tmp / name)


#: page -> how its examples' inputs are made
PAGES = {"render.md": _exx_inputs, "planner.md": _exx_inputs,
         "identification.md": _laser_inputs, "diagnose.md": _laser_inputs}


def doc_examples(text: str) -> list[tuple[str, list[str]]]:
    """(command, quoted output lines) of every ``$ mtcomp`` line in the page's code blocks."""
    out = []
    inside = False
    current = None          # the quoted lines of the command being read, or None
    for line in text.splitlines():
        if line.startswith("```"):
            inside, current = not inside, None
            continue
        if not inside:
            continue
        if line.startswith("$ mtcomp "):
            current = []
            out.append((line[2:], current))
        elif line.startswith("$ "):
            current = None                         # another program's command: not checked
        elif current is not None:
            current.append(line)
    return out


def _shape(line: str) -> str:
    return _NUMBER.sub("#", _TIME.sub("T", line)).strip()


def _numbers_agree(quoted: str, printed: str) -> str | None:
    """None when every number of ``quoted`` is that of ``printed`` within its last digit or 1 %,
    else what differs."""
    for q, p in zip(_NUMBER.findall(_TIME.sub("T", quoted)), _NUMBER.findall(_TIME.sub("T", printed))):
        digits = len(q.split(".")[1].split("e")[0].split("E")[0]) if "." in q else 0
        tol = max(10.0 ** -digits, 0.01 * abs(float(q)))
        if abs(float(q) - float(p)) > tol:
            return f"{q} quoted, {p} printed"
    return None


def check_quoted(quoted: list[str], printed: list[str]) -> list[str]:
    """The quoted lines that the printed output lacks, in order (a '...' line skips any lines;
    otherwise the lines must follow each other)."""
    problems = []
    i = 0
    gap = False
    for q in quoted:
        if q.strip() == "...":
            gap = True
            continue
        if not q.strip():
            continue
        j = i
        while j < len(printed) and _shape(printed[j]) != _shape(q):
            if not gap and printed[j].strip():
                break
            j += 1
        if j >= len(printed) or _shape(printed[j]) != _shape(q):
            problems.append(f"not printed: {q!r}")
            continue
        diff = _numbers_agree(q, printed[j])
        if diff:
            problems.append(f"{q!r}: {diff}")
        i, gap = j + 1, False
    return problems


def check_streams(quoted: list[str], out: list[str], err: list[str]) -> list[str]:
    """:func:`check_quoted` of a page's block against a command's two streams: the page shows them
    as a terminal does, mixed; a quoted line is looked for in standard error when only that has
    its words, and the order is checked within each stream ('...' between every two lines)."""
    err_shapes = {_shape(e) for e in err}
    out_shapes = {_shape(o) for o in out}
    to_err = [q for q in quoted if _shape(q) in err_shapes and _shape(q) not in out_shapes]
    to_out = [q for q in quoted if q not in to_err and q.strip() not in ("", "...")]
    spaced = lambda lines: [x for q in lines for x in ("...", q)]   # noqa: E731
    return check_quoted(spaced(to_out), out) + check_quoted(spaced(to_err), err)


def test_the_checker_catches_a_drifted_figure_and_a_missing_line():
    printed = ["before: max 4.000 um, rms 2.689 um", "0 blocks hit a bound", "wrote a.nc in 1.2 s"]
    assert check_quoted(["before: max 4.000 um, rms 2.689 um", "...", "wrote a.nc in 9.9 s"],
                        printed) == []
    assert check_quoted(["before: max 4.100 um, rms 2.689 um"], printed) \
        == ["'before: max 4.100 um, rms 2.689 um': 4.100 quoted, 4.000 printed"]
    assert check_quoted(["before: max 4.000 um, rms 2.689 um", "wrote a.nc in 1.2 s"], printed) \
        == ["not printed: 'wrote a.nc in 1.2 s'"]
    assert check_quoted(["a line nobody prints"], printed) == ["not printed: 'a line nobody prints'"]
    assert check_streams(["note: a", "wrote b"], ["wrote b"], ["note: a"]) == []
    assert check_streams(["note: a", "wrote b"], ["wrote b"], []) == ["not printed: 'note: a'"]


def test_every_page_with_command_examples_is_known_here():
    pages = {p.name for p in DOCS.glob("*.md") if doc_examples(p.read_text())}
    assert pages <= set(PAGES), f"examples not checked: {sorted(pages - set(PAGES))}"


@pytest.mark.parametrize("page", sorted(PAGES))
def test_the_examples_of_a_page_print_what_it_quotes(page, tmp_path, monkeypatch, capsys):
    examples = doc_examples((DOCS / page).read_text())
    assert examples, f"docs/{page} has no command example"
    PAGES[page](tmp_path)
    monkeypatch.chdir(tmp_path)
    problems = []
    for command, quoted in examples:
        args = command.split()[1:]
        rc = main(args)
        cap = capsys.readouterr()
        assert rc == 0, f"docs/{page}: `{command}` exited {rc}: {cap.err.strip()}"
        problems += [f"docs/{page}: `{command}`: {p}"
                     for p in check_streams(quoted, cap.out.splitlines(), cap.err.splitlines())]
    assert not problems, "\n".join(problems)


def test_the_planner_page_quotes_the_holes_as_written(tmp_path, monkeypatch, capsys):
    """docs/planner.md quotes the corrected hole lines: only the X words change."""
    _exx_inputs(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert main(["compensate", "xfyz", "MODEL.json", "holes.nc", "-o", "out.nc",
                 "--max-correction-um", "3", "--quiet"]) == 0
    capsys.readouterr()
    written = (tmp_path / "out.nc").read_text().splitlines()
    doc = (DOCS / "planner.md").read_text()
    for line in ("G81 X9.9996 Y5. Z-3. R2. F100", "X49.9980 Y5.", "X99.9970 Y20."):
        assert line in written and f"`{line}`" in doc
