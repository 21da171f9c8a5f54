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


@pytest.fixture(params=["compiled", "python"])
def reader_path(request, monkeypatch):
    """Each G-code reader and writer in turn: the compiled scanner ('compiled'; skipped without a C
    compiler) and the pure-Python one ('python', MTCOMP_NO_FAST_GCODE set)."""
    from mtcomp.toolpaths import _fast
    if request.param == "python":
        monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
    elif not _fast.available():
        pytest.skip("no C compiler: the compiled G-code path is not available")
    return request.param


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


@pytest.fixture
def refused_on_xfyz(tmp_path, capsys):
    """``refused(name, text)``: ``mtcomp compensate --quiet`` of the program ``text`` (written to
    ``tmp_path / name``) on xfyz with a zero model, which must refuse it: exit 2, one line on stderr
    (returned), no output written."""
    from mtcomp.cli import main
    from mtcomp.models import FittedModel, save_model

    def refused(name: str, text: str) -> str:
        prog = tmp_path / name
        prog.write_text(text)
        model = tmp_path / "model.json"
        save_model(model, FittedModel.zero(ErrorModel(load_machine("xfyz"))))
        out = tmp_path / "out.nc"
        assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and not out.exists(), err
        return err[0]
    return refused
