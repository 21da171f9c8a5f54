"""Reading a CSV file into header + string cells, and parsing its cells (docs/measurements.md).

This layer knows nothing about measurement kinds: it reads the header row and the data rows as
strings, checks the shape (no empty file, no duplicate or unnamed column, no ragged row; a file cut off
in its last row, one separated by semicolons or tabs, and decimal commas are refused with the fix
named, docs/measurements.md), and parses columns into numpy arrays with errors that name the file, the data row (1-based; the header is row 0)
and the column. Blank cells mean "not measured" and become NaN where a column allows it; the text
``nan`` or ``inf`` is refused everywhere, so that "not measured" has a single spelling.
"""
from __future__ import annotations

import csv
import io
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError

#: a number written with a decimal comma, e.g. ``-1,25``
_DECIMAL_COMMA = re.compile(r"^[+-]?\d*,\d+$")


@dataclass(frozen=True, eq=False)
class CsvTable:
    """A CSV file as read: original header and cells, plus the lookup by column name.

    path : the file, as given.
    header : (m,) original header cells, verbatim.
    rows : (n,) tuples of m original cells, verbatim (strings).
    row : (n,) int, 1-based data row number of each row (the header is row 0; a blank line in the
        file still counts, so row = file line - 1 for files without quoted line breaks).
    """

    path: str
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    row: np.ndarray

    @property
    def names(self) -> tuple[str, ...]:
        """(m,) column names as matched: stripped and lower-case."""
        return tuple(h.strip().lower() for h in self.header)

    def has(self, name: str) -> bool:
        return name in self.names

    def cells(self, name: str) -> list[str]:
        """(n,) stripped cells of column ``name`` (which must exist)."""
        j = self.names.index(name)
        return [r[j].strip() for r in self.rows]

    def floats(self, name: str, required: bool = False, scale: float = 1.0) -> np.ndarray:
        """(n,) float column times ``scale``; blank -> NaN, or an InputError when ``required``."""
        return parse_floats(self.cells(name), name, self.path, self.row, required) * scale

    def optional_floats(self, name: str, scale: float = 1.0, fill: float = math.nan) -> np.ndarray:
        """(n,) float column times ``scale``, or ``fill`` everywhere when the column is absent."""
        if not self.has(name):
            return np.full(len(self.rows), fill)
        return self.floats(name, scale=scale)

    def fail(self, message: str, index: int | None = None):
        """Raise InputError for this file, at data row ``row[index]`` when ``index`` is given."""
        raise InputError(message, self.path, row=None if index is None else int(self.row[index]))


def read_csv_table(path: str | os.PathLike) -> CsvTable:
    """Read ``path`` into a :class:`CsvTable`; InputError for a missing, empty or ragged file."""
    spath = os.fspath(path)
    p = Path(spath)
    if not p.exists():
        raise InputError("no such file", spath)
    if p.is_dir():
        raise InputError("is a folder, not a CSV file", spath)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise InputError("not a UTF-8 text file (expected a CSV file)", spath) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", spath) from None
    _check_not_toml_or_json(text, spath)
    reader = csv.reader(io.StringIO(text))
    header: list[str] | None = None
    rows: list[tuple[str, ...]] = []
    row_numbers: list[int] = []
    try:
        for cells in reader:
            if not cells or all(not c.strip() for c in cells):
                continue  # blank line
            if header is None:
                header = cells
                _check_header(header, spath)
                continue
            rows.append(tuple(cells))
            row_numbers.append(reader.line_num - 1)
    except csv.Error as exc:
        raise InputError(f"not a valid CSV file: {exc}", spath, row=max(reader.line_num - 1, 0)) \
            from None
    if header is None:
        raise InputError("empty file: expected a header row and data rows", spath)
    if not rows:
        raise InputError("no data rows below the header", spath)
    for i, cells in enumerate(rows):
        if len(cells) != len(header):
            _ragged(cells, len(header), i == len(rows) - 1, spath, row_numbers[i])
    if not text.endswith(("\n", "\r")):
        _check_cut_mid_row(header, rows, spath, row_numbers[-1])
    return CsvTable(spath, tuple(header), tuple(rows), np.asarray(row_numbers, dtype=np.int64))


#: the first line of a TOML file (a machine file: ``name = "vf2"``, ``[axes.X]``, a comment)
_TOML_START = re.compile(r'^\s*(\[[A-Za-z_][\w.]*\]|[A-Za-z_]\w*\s*=\s*\S)')


def _check_not_toml_or_json(text: str, path: str) -> None:
    """InputError when the file is a machine file (TOML) or a model file (JSON) given where a CSV
    file belongs: read as CSV its first line would pass for a header and the message would blame
    a row's cells."""
    first = next((ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")),
                 "")
    if first.lstrip().startswith("{"):
        raise InputError("a JSON file (a model file?), not a CSV measurement file: the machine file "
                         "comes first, then the measurement files", path)
    if _TOML_START.match(first) and "," not in first:
        raise InputError("a TOML file (a machine file?), not a CSV measurement file: the machine "
                         "file comes first, then the measurement files", path)


def _ragged(cells, n_columns: int, last: bool, path: str, row: int) -> None:
    """Raise the InputError of a row of ``len(cells)`` cells under a header of ``n_columns``, with
    the likely cause: a cut-off file (the last row short) or a decimal comma (a row too long)."""
    message = f"{len(cells)} cells but the header has {n_columns} columns"
    if last and len(cells) < n_columns:
        message += (" in the last row: the file looks cut off mid-row (an interrupted export or "
                    "copy); re-export or copy it again, or delete the incomplete last row")
    elif n_columns == 1:
        message += ("; the first line, read as the header, is one cell: a title or an instrument's "
                    "report lines before the table? The header row of column names comes first "
                    "(docs/measurements.md)")
    elif len(cells) > n_columns:
        message += ("; a decimal comma splits a number into two cells: write decimal points "
                    "(1.5, not 1,5)")
    raise InputError(message, path, row=row)


def _decimals(cell: str) -> int | None:
    """Digits after the decimal point of a plain decimal number (``-12.50`` -> 2, ``7`` -> 0), None
    for anything else (exponent notation, text)."""
    body = cell.lstrip("+-")
    whole, _, frac = body.partition(".")
    if not (whole or frac) or not (whole.isdigit() or not whole) or not (frac.isdigit() or not frac):
        return None
    return len(frac)


def _check_cut_mid_row(header, rows, path: str, row: int) -> None:
    """A file that ends without a line break may have been cut in the middle of its last cell. Refuse
    it when the last cell says so against the rest of its column: blank where every other row has a
    value, or a number with fewer decimals than every other value of the column (all plain decimals
    with at least one decimal). A complete file can always be accepted by ending it with a line break."""
    if len(rows) < 2:
        return
    last = rows[-1][-1].strip()
    others = [r[-1].strip() for r in rows[:-1]]
    name = header[-1].strip()
    fix = ("the file looks cut off (an interrupted export or copy): re-export or copy it again; if "
           "the row is complete, end the file with a line break")
    if not last and all(others):
        raise InputError(f"the file ends without a line break on a blank {name} where every other row "
                         f"has a value: {fix}", path, row=row)
    mine = _decimals(last)
    theirs = [_decimals(c) for c in others if c]
    if mine is None or not theirs or None in theirs:
        return
    fewest = min(theirs)
    if fewest >= 1 and mine < fewest:
        raise InputError(f"the file ends without a line break in the middle of what looks like a number: "
                         f"{last!r} has {mine} decimal(s) where every other value of {name} has at "
                         f"least {fewest}: {fix}", path, row=row)


def _check_header(header: list[str], path: str) -> None:
    seen: set[str] = set()
    for j, h in enumerate(header):
        name = h.strip().lower()
        if not name:
            raise InputError(f"header column {j + 1} has no name", path, row=0)
        if name in seen:
            raise InputError(f"column {name!r} appears twice in the header", path, row=0)
        seen.add(name)
    if len(header) == 1:
        for sep, what in ((";", "semicolons"), ("\t", "tabs")):
            if sep in header[0]:
                raise InputError(f"the header is one column {header[0].strip()!r}: the file is separated "
                                 f"by {what} (as spreadsheets write it where the decimal mark is a comma); "
                                 "save it comma separated, with a decimal point (1.5, not 1,5)",
                                 path, row=0)


def parse_floats(cells: list[str], column: str, path: str, row: np.ndarray,
                 required: bool = False) -> np.ndarray:
    """(n,) floats from stripped cells; blank -> NaN (or InputError when ``required``).

    Text that is not a number, and the text ``nan``/``inf``, raise InputError naming the row and column.
    """
    n = len(cells)
    if all(cells):  # fast path: every cell filled
        try:
            out = np.asarray(cells, dtype=float)
        except ValueError:
            out = None
        if out is not None and np.all(np.isfinite(out)):
            return out
    out = np.empty(n)
    for i, s in enumerate(cells):
        if not s:
            if required:
                raise InputError(f"column {column} is blank; a value is required", path, row=int(row[i]))
            out[i] = math.nan
            continue
        try:
            v = float(s)
        except ValueError:
            hint = ""
            if _DECIMAL_COMMA.match(s):
                hint = f" (a decimal comma? write {s.replace(',', '.')})"
            raise InputError(f"column {column}: {s!r} is not a number{hint}", path,
                             row=int(row[i])) from None
        if not math.isfinite(v):
            raise InputError(f"column {column}: {s!r} is not a finite number (leave the cell blank "
                             "for 'not measured')", path, row=int(row[i]))
        out[i] = v
    return out


def parse_ints(cells: list[str], column: str, path: str, row: np.ndarray, blank: int | None = None,
               minimum: int | None = None) -> np.ndarray:
    """(n,) int64 from cells holding whole numbers (``3`` or ``3.0``); blank -> ``blank`` or error."""
    vals = parse_floats(cells, column, path, row, required=blank is None)
    out = np.empty(len(cells), dtype=np.int64)
    for i, v in enumerate(vals):
        if math.isnan(v):
            out[i] = blank
            continue
        if v != round(v):
            raise InputError(f"column {column}: {cells[i]!r} is not a whole number", path,
                             row=int(row[i]))
        if minimum is not None and v < minimum:
            raise InputError(f"column {column}: {cells[i]!r} is below {minimum}", path, row=int(row[i]))
        out[i] = int(v)
    return out


def parse_signs(cells: list[str], column: str, path: str, row: np.ndarray,
                required: bool = False) -> np.ndarray:
    """(n,) int8 approach directions +1/-1 (``1``, ``+1``, ``-1``, ``1.0``); blank -> 0 (unknown).
    A word (``up``, ``fwd``, ``+``) is refused naming the two numbers the column takes."""
    for i, c in enumerate(cells):
        t = c.strip()
        if t and not t.lstrip("+-").replace(".", "", 1).isdigit() and t.lower() not in ("nan",):
            raise InputError(f"column {column}: {t!r} is not an approach direction: write +1 (the "
                             "axis moving towards +) or -1", path, row=int(row[i]))
    vals = parse_floats(cells, column, path, row, required=required)
    out = np.zeros(len(cells), dtype=np.int8)
    for i, v in enumerate(vals):
        if math.isnan(v):
            continue
        if v not in (1.0, -1.0):
            raise InputError(f"column {column}: {cells[i]!r} is not an approach direction "
                             "(+1 or -1)", path, row=int(row[i]))
        out[i] = int(v)
    return out
