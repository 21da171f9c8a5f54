"""Fixtures shared by several test files."""
import pytest

from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel


@pytest.fixture(scope="module")
def xfyz():
    """(machine, base ErrorModel) of the built-in 3-axis machine."""
    m = load_machine("xfyz")
    return m, ErrorModel(m)


@pytest.fixture(scope="module")
def cafxyz():
    """(machine, base ErrorModel) of the built-in CAFXYZ double-turntable machine."""
    m = load_machine("cafxyz")
    return m, ErrorModel(m)


@pytest.fixture(scope="session")
def _compiled_cache_dir(tmp_path_factory, worker_id):
    """One cache folder of compiled model code for the whole run, shared by pytest-xdist's workers
    (their temporary folders are siblings): a library compiled by one test is loaded, not compiled
    again, by every other test that compiles the same C."""
    root = tmp_path_factory.getbasetemp()
    if worker_id != "master":
        root = root.parent
    path = root / "compiled-cache"
    path.mkdir(mode=0o700, exist_ok=True)
    return path


@pytest.fixture
def shared_cache(_compiled_cache_dir, monkeypatch):
    """MTCOMP_CACHE_DIR set to the run's shared cache of compiled code (in-process caches cleared
    before and after): for tests that check what compiled code computes, not how it is cached."""
    from mtcomp.models import compiled
    monkeypatch.setenv("MTCOMP_CACHE_DIR", str(_compiled_cache_dir))
    compiled.forget_loaded()
    yield _compiled_cache_dir
    compiled.forget_loaded()
