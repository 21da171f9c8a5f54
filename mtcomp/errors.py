"""Errors raised for bad input.

Every error a user can cause (a malformed file, an unknown option, a value out of range) is raised as
:class:`InputError`. The command line turns it into one line on stderr and exit status 2, with no
traceback. Never use ``assert`` for input checks.
"""
from __future__ import annotations

import os


class InputError(ValueError):
    """Bad input: names the file, the line or row (when known) and the problem.

    Parameters
    ----------
    message : what is wrong, one sentence.
    path : the file, or None.
    line : 1-based line number in the file (G-code, TOML), or None.
    row : 1-based data row of a CSV file (the header is row 0), or None.
    """

    def __init__(self, message: str, path: str | os.PathLike | None = None,
                 line: int | None = None, row: int | None = None):
        self.message = message
        self.path = None if path is None else os.fspath(path)
        self.line = line
        self.row = row
        super().__init__(self.one_line())

    def one_line(self) -> str:
        where = ""
        if self.path is not None:
            where = self.path
            if self.line is not None:
                where += f":{self.line}"
            elif self.row is not None:
                where += f": row {self.row}"
            where += ": "
        elif self.line is not None:
            where = f"line {self.line}: "
        elif self.row is not None:
            where = f"row {self.row}: "
        return (where + self.message).replace("\n", " ")
