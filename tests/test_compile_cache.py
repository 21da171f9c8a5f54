"""One cache folder for compiled code (mtcomp.io.cache): the model's C and the G-code scanner both
follow MTCOMP_CACHE_DIR, else XDG_CACHE_HOME, else ~/.cache, and both fall back to a temporary
folder when that cannot be used. Checked in fresh processes whose environment points every folder
into tmp_path."""
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

import mtcomp
from mtcomp.io import cache

ROOT = Path(mtcomp.__file__).resolve().parent.parent

#: compiles the G-code scanner and one small model function, then prints the folders they are in
SCRIPT = """
import numpy as np
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, compiled
from mtcomp.toolpaths import _fast
assert _fast.available(), "the G-code scanner did not compile"
model = ErrorModel(load_machine("xfyz").with_basis("polynomial"))
q = np.zeros((3, 3)); p = np.zeros(model.n_params); c = model.default_context(3)
assert compiled.call(model, "pose_function", model.pose_function, q, p, c, required=True) is not None
print(compiled.cache_dir())
"""

needs_cc = pytest.mark.skipif(not (shutil.which("cc") or shutil.which("gcc")), reason="no C compiler")


def _run(tmp_path, **env):
    """Run SCRIPT with HOME, TMPDIR and the cache variables of ``env`` (None: unset)."""
    home, tmp = tmp_path / "home", tmp_path / "tmp"
    home.mkdir(exist_ok=True)
    tmp.mkdir(exist_ok=True)
    full = dict(os.environ, HOME=str(home), TMPDIR=str(tmp), PYTHONPATH=str(ROOT),
                MTCOMP_COMPILE_MIN_POSES="1")
    for k in ("MTCOMP_CACHE_DIR", "XDG_CACHE_HOME", "MTCOMP_NO_FAST_GCODE", "MTCOMP_CC"):
        full.pop(k, None)
    full.update({k: str(v) for k, v in env.items() if v is not None})
    r = subprocess.run([sys.executable, "-c", SCRIPT], env=full, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    return Path(r.stdout.strip().splitlines()[-1])


def _libraries(folder: Path) -> set:
    return {("gcode" if f.name.startswith("gcode_") else "model") for f in folder.glob("*.so")}


@needs_cc
def test_mtcomp_cache_dir_moves_both_caches(tmp_path):
    chosen = tmp_path / "chosen"
    assert _run(tmp_path, MTCOMP_CACHE_DIR=chosen, XDG_CACHE_HOME=tmp_path / "xdg") == chosen
    assert _libraries(chosen) == {"gcode", "model"}
    # nothing anywhere else
    for other in (tmp_path / "xdg", tmp_path / "home", tmp_path / "tmp"):
        assert not list(other.rglob("*.so")), other


@needs_cc
def test_without_it_both_go_to_the_xdg_then_the_home_cache(tmp_path):
    assert _run(tmp_path, XDG_CACHE_HOME=tmp_path / "xdg") == tmp_path / "xdg" / "mtcomp"
    assert _libraries(tmp_path / "xdg" / "mtcomp") == {"gcode", "model"}
    home_cache = tmp_path / "home" / ".cache" / "mtcomp"
    assert _run(tmp_path) == home_cache
    assert _libraries(home_cache) == {"gcode", "model"}


@needs_cc
def test_an_unusable_home_cache_falls_back_to_the_temporary_folder(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")                  # (root may write anywhere: use a file)
    got = _run(tmp_path, XDG_CACHE_HOME=blocker / "xdg")
    uid = os.getuid() if hasattr(os, "getuid") else "user"
    assert got == tmp_path / "tmp" / f"mtcomp-{uid}"
    assert _libraries(got) == {"gcode", "model"}


def test_the_rule_in_process(tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "t"))
    monkeypatch.delenv("MTCOMP_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "x"))
    uid = os.getuid() if hasattr(os, "getuid") else "user"
    assert cache.cache_dirs() == [tmp_path / "x" / "mtcomp", tmp_path / "t" / f"mtcomp-{uid}"]
    assert cache.private_cache_dir() == tmp_path / "x" / "mtcomp"
    # a folder others may write to is skipped (code is loaded from it)
    shared = tmp_path / "shared"
    (shared / "mtcomp").mkdir(parents=True)
    (shared / "mtcomp").chmod(0o777)
    monkeypatch.setenv("XDG_CACHE_HOME", str(shared))
    assert cache.private_cache_dir() == tmp_path / "t" / f"mtcomp-{uid}"
    # MTCOMP_CACHE_DIR is the only folder tried: refused, not replaced
    monkeypatch.setenv("MTCOMP_CACHE_DIR", str(shared / "mtcomp"))
    assert cache.cache_dirs() == [shared / "mtcomp"]
    with pytest.raises(cache.CacheDirError, match="writable by other users"):
        cache.private_cache_dir()
