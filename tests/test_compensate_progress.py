"""compensate's progress lines come early, whatever runs: the reader tells the lines it has read
(a tool centre point program is read line by line in Python: 32,768 rows before the planner has a
chunk), a compiler run of the model's C code is told when it starts and ends, and a thread writes
a line every few seconds from what they told."""
import io
import re
import threading
import time

import pytest

from mtcomp.cli import main
from mtcomp.commands.compensate import Progress
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, compiled, save_model
from mtcomp.toolpaths import iter_segment_chunks

XFYZ = load_machine("xfyz")


def _tcp_program(path, n):
    """A LinuxCNC tool centre point program of n feed moves (C turns, X Y on a circle)."""
    lines = ["G21 G90 G17 G94", "M428", "G0 X40 Y0 Z60 A-30 C0", "G1 Z20 F400"]
    lines += [f"X{40 - k * 1e-3:.4f} Y{k * 1e-2:.4f} A-30 C{k * 0.1:.3f}" for k in range(n)]
    path.write_text("\n".join(lines + ["M429", "M2"]) + "\n")
    return path


def test_the_reader_tells_the_lines_it_reads_before_its_first_chunk(tmp_path, reader_path):
    prog = _tcp_program(tmp_path / "tcp.ngc", 2100)
    events = []
    for chunk in iter_segment_chunks(prog, load_machine("cafxyz"), chunk_size=1 << 15,
                                     progress=lambda k: events.append(("read", k))):
        events.append(("chunk", len(chunk)))
    first_chunk = events.index(("chunk", 2102))
    told = [k for what, k in events[:first_chunk] if what == "read"]
    # every 1024 lines interpreted in Python (the scanner hands tool centre point lines over)
    assert {1024, 2048} <= set(told) and told == sorted(told)
    assert events[first_chunk + 1:] == []


def test_the_expansion_of_a_program_with_code_tells_the_lines_it_runs(tmp_path, monkeypatch):
    """A program with code is run before its moves are read (a long loop takes minutes): the lines
    executed are told as it runs, every PROGRESS_EVERY (here 16) lines of the expansion."""
    from mtcomp.toolpaths import source
    monkeypatch.setattr(source, "PROGRESS_EVERY", 16)
    prog = tmp_path / "loop.ngc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z10\n#<k> = 0\no1 while [#<k> LT 50]\nG1 X[#<k>] F100\n"
                    "#<k> = [#<k> + 1]\no1 endwhile\nM2\n")
    told = []
    with source.open_program(prog, progress=told.append) as src:
        assert src.executed == 53               # G21, G0, 50 moves, M2
    # the expansion's lines: its comment first, then the program's; told at 16, 32, 48
    assert told == [15, 31, 47]
    stream = io.StringIO()
    with Progress(stream, time.perf_counter(), every_s=0.01) as progress:
        progress.io("expanded", 47)
        _wait_for(stream, "mtcomp compensate: running the program's code, 47 lines executed (")
        progress.io("read", 20)
        _wait_for(stream, "mtcomp compensate: 20 lines read (")


def test_a_compiler_run_is_told_when_it_starts_and_ends(tmp_path, monkeypatch):
    compiler = compiled.find_compiler()
    if compiler is None:
        pytest.skip("no C compiler")
    cache = tmp_path / "cache"
    cache.mkdir(mode=0o700)
    monkeypatch.setenv("MTCOMP_CACHE_DIR", str(cache))
    src = "double mtcomp_progress_test(double x) { return 2.0 * x; }\n"
    told = []
    with compiled.compile_notices(lambda name, started: told.append((name, started))):
        compiled.compile_source(src, compiler, "f")
        compiled.compile_source(src, compiler, "f")        # from the cache: no compiler run
    compiled.compile_source(src + "\n", compiler, "g")     # nobody listens any more
    assert told == [("f", True), ("f", False)]


def _wait_for(stream, text, timeout_s=5.0):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if text in stream.getvalue():
            return
        time.sleep(0.005)
    raise AssertionError(f"no {text!r} in {stream.getvalue()!r}")


def test_progress_lines_say_what_runs_every_few_seconds():
    stream = io.StringIO()
    t0 = time.perf_counter()
    with Progress(stream, t0, every_s=0.01) as progress:
        _wait_for(stream, "mtcomp compensate: reading the program (")
        progress.io("read", 2048)
        progress.compiling("tip_pjacobian_function", True)
        _wait_for(stream, "2048 lines read, compiling the model's standard-error function to C, ")
        progress.compiling("tip_pjacobian_function", False)
        progress.planned(4096)
        progress.io("written", 100)
        _wait_for(stream, "2048 lines read, 4096 blocks planned, written up to line 100 (")
    after = stream.getvalue()
    time.sleep(0.05)
    assert stream.getvalue() == after          # the thread has stopped
    assert not any(t.name == "mtcomp-progress" for t in threading.enumerate())


def test_no_progress_line_in_a_short_run_or_when_quiet():
    stream = io.StringIO()
    with Progress(stream, time.perf_counter(), every_s=60.0) as progress:
        progress.io("read", 10)
    assert stream.getvalue() == ""
    with Progress(None, time.perf_counter(), every_s=0.001) as progress:
        progress.io("read", 10)
        time.sleep(0.02)
    assert not any(t.name == "mtcomp-progress" for t in threading.enumerate())


def test_compensate_reports_the_lines_read_before_any_block_is_planned(tmp_path, monkeypatch,
                                                                        capsys):
    # the Python reader (as for a tool centre point program) on a 3-axis program whose last move
    # leaves the travel: its lines read are told before the planner's check of the first chunk
    # refuses it (one line more, the error, and with --quiet that line alone)
    monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
    monkeypatch.setattr(Progress, "EVERY_S", 0.01)
    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z10\nG1 Z0 F500\n"
                    + "".join(f"G1 X{k % 50 + 1}.{k % 7} Y{k % 40}\n" for k in range(2100))
                    + "G1 X900\nM2\n")
    model = tmp_path / "model.json"
    save_model(model, FittedModel.zero(ErrorModel(XFYZ)))
    args = ["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o.nc")]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "p.nc:2104: X 900.0000 mm is outside the travel" in err[-1]
    said = re.compile(r"mtcomp compensate: (\d+) lines read \(")
    read = [int(m.group(1)) for m in map(said.match, err[:-1]) if m]
    assert read and max(read) >= 1024 and read == sorted(read), err
    assert main(args + ["--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "outside the travel" in err[0]


def test_a_travel_refusal_names_the_work_offset_taken_as_zero(tmp_path, capsys):
    """A program written for G54 = (X -500) refused for X outside the travel says that G54 was
    taken as 0 because nobody gave it (a new user forgot --offsets and read only 'outside the
    travel'); with the offset given it is accepted, and a program with no work offset the user
    left out is refused as before, without the hint."""
    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90 G54\nG0 X300 Y0 Z10\nG1 Z0 F500\nG1 X450\nM2\n")
    model = tmp_path / "model.json"
    save_model(model, FittedModel.zero(ErrorModel(XFYZ)))
    base = ["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o.nc"), "--quiet"]
    assert main(base) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "X 450.0000 mm is outside the travel" in err[0]
    assert "work offset G54 taken as 0" in err[0] and "--offsets" in err[0]
    assert not (tmp_path / "o.nc").exists()
    assert main(base + ["--work-offset", "G54=X-500,Y0,Z0"]) == 0
    capsys.readouterr()
    assert main(base + ["--work-offset", "G54=X500,Y0,Z0"]) == 2
    err = capsys.readouterr().err
    assert "outside the travel" in err and "taken as 0" not in err
    # the offset given without its X: that axis of it was taken as 0 (a user's G54=X..,Y.. left
    # out Z and read only that Z was outside the travel)
    assert main(base + ["--work-offset", "G54=Y0,Z0"]) == 2
    err = capsys.readouterr().err
    assert "with X of work offset G54 taken as 0 (not given)" in err
