"""Where a program becomes the flat text the reader reads: its dialect, and its expansion.

:func:`open_program` is the one place every reader of programs goes through (the segment stream,
the writer, ``read_program``; so ``compensate``, ``render`` and the CMM measurement model). It
finds the program's dialect (given, or :func:`~.dialect.detect`), and when the program has code
to compute (LinuxCNC O-words, parameters and expressions, polar words; Fanuc macro B) it runs
that code (:mod:`.ngc`, :mod:`.macro`) into a temporary file of the lines the controller executes,
whose first line is a comment saying so. A program without such code is read as it is, byte for
byte. The :class:`ProgramSource` handed on is path-like (the file to read) and carries the
dialect, and the map from expanded lines to the source's lines that errors are named by.
"""
from __future__ import annotations

import contextlib
import os
import re
import tempfile
from array import array
from dataclasses import dataclass, field

from ..errors import InputError
from .dialect import Dialect, dialect_named, foreign_language, needs_expansion
from .words import strip_comments

# the languages' readers (.ngc, .macro, .heidenhain, .sinumerik) are imported where a program
# needs one: a plain G-code program is read without them
_LANGUAGE = {"ngc": "O-word control flow, parameters and expressions",
             "macro": "macro variables, IF, GOTO, WHILE, subprogram and macro calls",
             "beagleg": "BeagleG's parameters, expressions and WHILE loops"}


@dataclass
class ProgramSource(os.PathLike):
    """A program as the reader reads it.

    path : the file read (the source, or its expansion). source : the user's file. dialect : its
    :class:`~.dialect.Dialect`; why : how it was found ('given', 'detected from line N: ...').
    line_map : for an expanded program, the source line (1-based) of each of its lines (0 for
    the first, the comment), else None. executed : lines written by the expansion.
    error : the InputError that stopped the expansion (an error in the program's code), or None:
    ``path`` then holds the lines executed before it, and the readers raise it after reading them
    (:meth:`raise_error`), so that an error of an earlier executed line is told first.
    """

    path: str
    source: str
    dialect: Dialect
    why: str
    line_map: array | None = None
    executed: int = 0
    source_lines: int = 0
    notes: list = field(default_factory=list)
    #: what makes the corrections depend on the feed (a model's feed terms, temperatures looked up
    #: at each block's time), as compensate says it; empty where nothing does
    feed_use: str = ""
    #: the distinct sets of work offsets the program sets itself (G10 L2/L20), numbered by the
    #: reader (:mod:`.programmed`) and applied by :meth:`~.offsets.ProgramSetup.apply`
    work_offset_sets: list = field(default_factory=list)
    #: what each G10 line did to the offsets, (line, (wcs, codes)) in line order (:mod:`.programmed`)
    offset_writes: list = field(default_factory=list)
    #: the frame changes the program makes itself (G52, G68, mirror, scaling), (line, frame) in
    #: line order, recorded by the reader (:mod:`.frames`) and applied by ProgramSetup.apply
    local_frames: list = field(default_factory=list)
    #: where the program switches tool centre point mode on: line -> code ('M428', 'G43.4'),
    #: recorded by the reader (:class:`~.modal.ModalState`)
    tcp_switches: dict = field(default_factory=dict)
    #: the W quill's position before and after each line that changes it: line -> (mm, mm), NaN
    #: where not known, recorded by the reader and applied by ProgramSetup.apply (:mod:`.quill`)
    quill_moves: dict = field(default_factory=dict)
    _map_array: object = field(default=None, repr=False)     # line_map as an int64 array, once
    #: a Heidenhain conversational program: its :class:`~.heidenhain.Translation` (``path`` is
    #: then its G-code equivalent, line for line; the writer writes the conversational form)
    heidenhain: object = None
    #: a Siemens Sinumerik program: its :class:`~.sinumerik.Translation` (``path`` is then its
    #: G-code equivalent, ``line_map`` the source line of each of its lines; the writer writes
    #: the Sinumerik form)
    sinumerik: object = None
    #: a program in a fixed format (the machine file's ``fixed_format``): its
    #: :class:`~.fixed_format.FixedFormat` (``path`` is then its G-code with points, line for line;
    #: the writer writes the words back in the format)
    fixed: object = None
    error: InputError | None = None
    #: the expanded lines (1-based) written as the controller computes them, from a value it holds
    #: (:class:`~.lines.ControllerLine`): line -> (the text the reader reads, the letters of the
    #: words of such values). The reader passes them through (:mod:`.controller_values`)
    controller_lines: dict = field(default_factory=dict)

    def __fspath__(self) -> str:
        return self.path

    def raise_error(self) -> None:
        """Raise the error that stopped the expansion, if any: called by the readers once every
        line before it has been read (and its rows handed out)."""
        if self.error is not None:
            raise self.error

    @property
    def expanded(self) -> bool:
        return self.line_map is not None and self.sinumerik is None

    @property
    def translated(self) -> bool:
        """A program read through its G-code equivalent and written back in its own form, one
        output block per source block (Heidenhain conversational, Sinumerik)."""
        return self.heidenhain is not None or self.sinumerik is not None

    def locate(self, line: int | None) -> tuple[str, int | None, str]:
        """(file, line, suffix for the message) to name a line of ``path`` by."""
        if self.line_map is None or line is None:
            return self.source, line, ""
        src = self.line_map[line - 1] if 0 < line <= len(self.line_map) else 0
        if self.sinumerik is not None:
            return self.source, (src or None), ""
        return self.source, (src or None), f" (line {line} of the expanded program)"

    def source_lines_of(self, lines):
        """(n,) int64: the source line of each of ``lines`` (lines of ``path``, 1-based); the lines
        themselves for a program read as it is. The map is turned into an array once."""
        import numpy as np
        lines = np.asarray(lines, np.int64)
        if self.line_map is None:
            return lines
        if self._map_array is None:
            self._map_array = np.asarray(self.line_map, np.int64)
        return self._map_array[lines - 1]

    def summary(self) -> str:
        """'dialect: fanuc (detected from line 2: O1234)'."""
        return f"dialect: {self.dialect.name} ({self.why})"


def _header(source: str, language: str, dialect: Dialect) -> str:
    """The expansion's first line; it names the dialect (but generic), so that the written program
    is read with the same rules when it is read again (``dialect.detect``: a comment naming it)."""
    name = os.path.basename(source).replace("(", "[").replace(")", "]")
    rules = "" if dialect.name == "generic" else f" for {dialect.name}"
    return (f"(expanded by mtcomp from {name}{rules}: {language} computed, one line for each line "
            "the controller executes)")


_PROGRAM_END_RE = re.compile(r"(?i)\bm0*(?:2|30)(?![\d.])")
#: a Fanuc or Haas program number line: O1234 (or :1234), a comment after it
_PROGRAM_NUMBER_RE = re.compile(r"^\s*[Oo:]\s*\d+\s*(?:\([^()]*\)\s*)*$")


#: how often (lines executed) the expansion tells its progress
PROGRESS_EVERY = 4096


def _expand(source: str, dialect: Dialect, max_steps: int | None, max_lines: int | None,
            progress=None):
    """(temporary file, line map, lines written, source lines, the InputError that stopped the run
    or None, notes), or None when nothing changes. ``progress``: callable(lines executed), told
    every PROGRESS_EVERY lines. An error in the code stops the run at its line: the file holds the
    lines executed before it (the error is the readers' to raise after them), but a runaway loop's
    (``runaway``), a fault of the whole run, is raised at once."""
    from . import macro, ngc
    language = _LANGUAGE[dialect.language]
    limits = {"max_steps": ngc.MAX_STEPS if max_steps is None else max_steps,
              "max_lines": ngc.MAX_LINES if max_lines is None else max_lines}
    with open(source, "rb") as f:
        raws = f.read().split(b"\n")          # lines as the reader counts them ('\n' ends one)
    raws = [r + b"\n" for r in raws[:-1]] + ([raws[-1]] if raws[-1] else [])
    if raws and raws[0].startswith(b"\xef\xbb\xbf"):
        raws[0] = raws[0][3:]
    texts = [r.decode("latin-1").rstrip("\r\n") for r in raws]
    ending = "\r\n" if raws and raws[0].endswith(b"\r\n") else "\n"
    if dialect.language == "ngc":
        run = ngc.NgcRun(texts, source, **limits)
    elif dialect.language == "beagleg":
        from .beagleg import to_ngc
        run = ngc.NgcRun(to_ngc(texts, source), source, **limits)
    else:
        run = macro.MacroRun(texts, source, **limits, dialect=dialect.name)
    # the expanded program's lines (0-based) -> the source's lines (1-based; 0: the header)
    line_map = array("l")
    header = (_header(source, language, dialect) + ending).encode("latin-1")   # the first line
    # a tape's end % stays its last line (what follows the program's end is not run, but the
    # controller reads the tape to it)
    tape = bool(raws) and raws[0].strip() == b"%"
    # the header follows a tape's opening % and, on a Fanuc or Haas, the program number line after
    # it (a controller takes the number from the line after the %)
    lead = int(tape) + int(tape and dialect.language != "ngc" and len(texts) > 1
                           and _PROGRAM_NUMBER_RE.match(texts[1]) is not None)
    same, last, stopped, notes, held = True, -1, None, [], {}
    fd, tmp = tempfile.mkstemp(prefix="mtcomp-expanded-", suffix=".nc")
    try:
        with os.fdopen(fd, "wb") as out:
            def write(i, text):
                if text is None:
                    raw = raws[i]
                    out.write(raw if raw.endswith(b"\n") else raw + ending.encode())
                else:
                    own = raws[i][len(raws[i].rstrip(b"\r\n")):] or ending.encode()
                    out.write(text.encode("latin-1", "replace") + own)
                    if hasattr(text, "reading"):        # a ControllerLine
                        held[len(line_map) + 1] = (text.reading, text.unknown)
                line_map.append(i + 1)
            try:
                headed = False
                for i, text in run.run():
                    if not headed and i >= lead:      # first, or after the lines it follows
                        out.write(header)
                        line_map.append(0)
                        headed = True
                    same = same and text is None and i == last + 1
                    write(i, text)
                    if not headed and i >= lead - 1:
                        out.write(header)
                        line_map.append(0)
                        headed = True
                    last = i
                    if progress is not None and not len(line_map) % PROGRESS_EVERY:
                        progress(len(line_map) - 1)
            except InputError as exc:
                if getattr(exc, "runaway", False):
                    raise
                stopped = exc
            if stopped is None:
                same = _after_the_run(write, raws, texts, last, tape) and same
                ran_nothing = run.check_ran() if hasattr(run, "check_ran") else None
                notes += [ran_nothing] if ran_nothing else []
        if stopped is None and same and len(line_map) - 1 == len(raws):
            os.unlink(tmp)
            return None
    except BaseException:
        os.unlink(tmp)
        raise
    return tmp, line_map, max(len(line_map) - 1, 0), len(raws), stopped, (notes, held)


def _after_the_run(write, raws, texts, last: int, tape: bool) -> bool:
    """Write what follows the lines a run executed (``last``: the last source line, 0-based, -1
    for none); False when that is not the source's next line (the expansion differs)."""
    if last >= 0 and _PROGRAM_END_RE.search(strip_comments(texts[last])):
        # what follows the program's end (M2/M30) is kept as it is: the controller runs none of
        # it (its subprograms, a tape's %, notes), and the reader passes it through
        for k in range(last + 1, len(raws)):
            write(k, None)
        return True
    end = next((k for k in range(len(raws) - 1, last, -1) if raws[k].strip() == b"%"), None)
    if tape and end is not None and raws[last].strip() != b"%":
        write(end, None)
        return end == last + 1
    return True


def _translated(source: str, d: Dialect, why: str):
    """A program in a controller's own language (Heidenhain conversational, Siemens Sinumerik)
    as a ProgramSource of its G-code equivalent."""
    if not os.path.isfile(source):
        raise InputError("no such file", source)
    sinumerik = d.language == "sinumerik"
    if sinumerik:
        from .sinumerik import translate
    else:                           # conversational or DIN/ISO
        from .heidenhain_iso import translate
    translation = translate(source)
    fd, tmp = tempfile.mkstemp(prefix=f"mtcomp-{d.language}-", suffix=".nc")
    try:
        with os.fdopen(fd, "w", encoding="latin-1", newline="\n") as out:
            out.write("".join(g + "\n" for g in translation.gcode))
        if sinumerik:
            yield ProgramSource(tmp, source, d, why, line_map=translation.line_map,
                                sinumerik=translation)
        else:
            yield ProgramSource(tmp, source, d, why, heidenhain=translation)
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def _fixed(source: str, d: Dialect, why: str, digits: tuple):
    """A program whose words are written in a fixed format as a ProgramSource of its G-code with
    points (:mod:`.fixed_format`)."""
    from .fixed_format import FixedFormat, read_lines, translate
    if not os.path.isfile(source):
        raise InputError("no such file", source)
    raws = read_lines(source)
    texts = [r.decode("latin-1").rstrip("\r\n") for r in raws]
    fixed = FixedFormat(digits)
    gcode = translate(texts, fixed, source)
    fd, tmp = tempfile.mkstemp(prefix="mtcomp-fixed-", suffix=".nc")
    try:
        with os.fdopen(fd, "wb") as out:
            for raw, g in zip(raws, gcode):
                out.write(g.encode("latin-1") + raw[len(raw.rstrip(b"\r\n")):])
        if d.language is not None and needs_expansion(tmp, macro_calls=d.language == "macro"):
            raise InputError(f"a program with code ({_LANGUAGE[d.language]}) is not read in a "
                             "fixed format (the machine file's fixed_format)", source)
        note = (f"note: the words are read in the fixed format {fixed.name()} (the machine file's "
                f"fixed_format), the corrected ones written back in it, rounded to its resolution "
                f"({10.0 ** -digits[1]:g})")
        yield ProgramSource(tmp, source, d, why, fixed=fixed, notes=[note])
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


@contextlib.contextmanager
def open_program(path, dialect: str | None = None, *, max_steps: int | None = None,
                 max_lines: int | None = None, progress=None, fixed_format=None):
    """The program at ``path`` as a :class:`ProgramSource` (see the module docstring); a
    ProgramSource is handed back as it is. ``dialect``: a name of :data:`~.dialect.DIALECTS`, or
    None to detect it. ``max_steps``, ``max_lines``: the limits of an expansion (None:
    :data:`.ngc.MAX_STEPS`, :data:`.ngc.MAX_LINES`). ``progress``: callable(lines executed),
    told as a program with code is run (every PROGRESS_EVERY lines), or None. The temporary file
    of an expansion is removed on leaving the context. Code that cannot be run is an InputError
    (file and source line named) that the readers raise once the lines executed before it are
    read (``ProgramSource.error``); a loop that does not end is raised here. ``fixed_format``:
    (digits before, after the point) where the machine reads words in a fixed format
    (:mod:`.fixed_format`), or None."""
    if isinstance(path, ProgramSource):
        yield path
        return
    source = os.fspath(path)
    foreign = foreign_language(source) if dialect is None else None
    if foreign is not None:
        line, text, name, what = foreign
        article = "an" if name[0] in "AEIOU" else "a"
        raise InputError(f"{article} {name} program ({text!r}): its language ({what}) is not read "
                         "by mtcomp; give --dialect generic to read it as plain G-code", source,
                         line=line)
    d, why = dialect_named(dialect, source)
    if d.language in ("heidenhain", "sinumerik"):
        yield from _translated(source, d, why)
        return
    if fixed_format is not None:
        yield from _fixed(source, d, why, fixed_format)
        return
    expansion = None
    if d.language is not None and os.path.isfile(source) and needs_expansion(
            source, macro_calls=d.language == "macro"):
        expansion = _expand(source, d, max_steps, max_lines, progress)
    if expansion is None:
        yield ProgramSource(source, source, d, why)
        return
    tmp, line_map, executed, n, stopped, (notes, held) = expansion
    try:
        yield ProgramSource(tmp, source, d, why, line_map, executed, n, notes=notes, error=stopped,
                            controller_lines=held)
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
