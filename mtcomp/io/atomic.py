"""Writing outputs safely: to a temporary file beside the target, renamed at the end.

A failed run leaves nothing behind, and an input file is never overwritten.
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
from pathlib import Path

from ..errors import InputError


def same_file(a, b) -> bool:
    """The same path, via a symlink, or a hard link to the same file (paths or strings)."""
    a, b = Path(a), Path(b)
    try:
        if a.resolve() == b.resolve():
            return True
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except (OSError, ValueError, RuntimeError):      # a NUL in the name, a symlink loop ...
        return str(a) == str(b)


def check_output_path(out: str | os.PathLike, inputs: list[str | os.PathLike] = (),
                      suffix: str | None = None, what: str = "the output") -> Path:
    """Refuse an output that is one of the inputs, that is a folder, whose folder does not exist, or
    (with ``suffix``, e.g. '.png') whose name does not end so (``what`` names it in the message)."""
    out_p = Path(out)
    for inp in inputs:
        if same_file(Path(inp), out_p):
            raise InputError("output would overwrite an input file", out)
    if out_p.is_dir():
        raise InputError("is a folder: name the output file", out)
    if suffix is not None and out_p.suffix.lower() != suffix:
        raise InputError(f"{what} is written as {suffix[1:].upper()}: give the file a {suffix} name", out)
    parent = out_p.resolve().parent
    if not parent.is_dir():
        raise InputError(f"output folder {parent} does not exist", out)
    return out_p


def _digest(path: str) -> str | None:
    """The file's SHA-256, None when it cannot be read (its reader says why)."""
    try:
        with open(path, "rb") as f:
            return hashlib.file_digest(f, "sha256").hexdigest()
    except (OSError, ValueError):
        return None


def check_distinct_inputs(paths: list[str | os.PathLike]) -> None:
    """Refuse a data file given twice (by the same path, a symlink or a hard link), or a copy of
    another byte for byte (the same part saved under two names): its readings would count twice
    and pass for repeats (repeated measurements differ at least by their noise)."""
    seen: list[tuple[str, str | None]] = []
    for p in map(os.fspath, paths):      # named as typed: Path("./a.csv") would print a.csv
        digest = _digest(p)
        for q, other in seen:
            if same_file(Path(p), Path(q)):
                raise InputError(f"given twice (also as {q}): its readings would count twice", p)
            if digest is not None and digest == other:
                raise InputError(f"the same bytes as {q} (a copy under another name?): its readings "
                                 "would count twice; give each measurement once", p)
        seen.append((p, digest))


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "w", newline: str | None = None):
    """Open a temporary file next to ``path``; rename it onto ``path`` only if the block succeeds."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.resolve().parent)
    try:
        if "b" in mode:
            f = os.fdopen(fd, mode)
        else:
            f = os.fdopen(fd, mode, encoding="utf-8", newline=newline)
        with f:
            yield f
        # mkstemp makes the file private (0600); an output gets the permissions any new file of the
        # user gets (0666 less the umask), so that a controller PC or a colleague can read it
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
