"""Where mtcomp keeps compiled code: one folder, one rule, for the model's C (:mod:`mtcomp.models.compiled`)
and the G-code scanner (:mod:`mtcomp.toolpaths._fast`).

The folder is ``$MTCOMP_CACHE_DIR`` when it is set (that folder only: it is the user's choice), else
``$XDG_CACHE_HOME/mtcomp``, else ``~/.cache/mtcomp``; when that one cannot be used (a read-only or
missing home), ``<temp>/mtcomp-<uid>``. A folder is used only if it can be created, belongs to this
user, nobody else can write to it (code is loaded from it) and this user can write to it.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path


class CacheDirError(OSError):
    """No cache folder can be used; the message says why for each one tried."""


def cache_dirs() -> list[Path]:
    """The folders to try, in order (none is created here)."""
    env = os.environ.get("MTCOMP_CACHE_DIR")
    if env:
        return [Path(env)]
    xdg = os.environ.get("XDG_CACHE_HOME")
    try:
        base = Path(xdg) if xdg else Path.home() / ".cache"
        first = [base / "mtcomp"]
    except RuntimeError:            # no home directory to be found
        first = []
    user = os.getuid() if hasattr(os, "getuid") else "user"
    return first + [Path(tempfile.gettempdir()) / f"mtcomp-{user}"]


def _problem(d: Path) -> str | None:
    """Why folder ``d`` cannot hold code mtcomp loads (None: it can); creates it if missing."""
    try:
        d.mkdir(parents=True, exist_ok=True, mode=0o700)
        st = d.stat()
    except OSError as exc:
        return f"cannot create cache directory {d}: {exc}"
    if hasattr(os, "getuid") and (st.st_uid != os.getuid() or st.st_mode & 0o022):
        return f"cache directory {d} is writable by other users; not loading code from it"
    if not os.access(d, os.W_OK | os.X_OK):
        return f"cache directory {d} is not writable"
    return None


def private_cache_dir() -> Path:
    """The first folder of :func:`cache_dirs` that can be used, created if needed. Raises
    CacheDirError naming each folder tried and its problem."""
    problems = []
    for d in cache_dirs():
        problem = _problem(d)
        if problem is None:
            return d
        problems.append(problem)
    raise CacheDirError("; ".join(problems))
