"""Streaming: memory stays flat with program length (read, correct in windows, write)."""
import tracemalloc

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.toolpaths import _fast, iter_segment_chunks, write_corrected

XFYZ = load_machine("xfyz")


def _program(path, n):
    rng = np.random.default_rng(n)
    xyz = np.cumsum(rng.normal(0, 0.3, (n, 3)), axis=0)
    lines = ["%", "G21 G90", "G0 X0 Y0 Z5", "G1 Z0 F800"]
    for i, (x, y, z) in enumerate(xyz):
        lines.append(f"X{x:.4f} Y{y:.4f} Z{z:.4f}")
        if i % 500 == 499:
            lines.append(f"G2 X{x + 1:.4f} Y{y:.4f} I0.5 J0 (ARC)\nG1 X{x:.4f} Y{y:.4f}")
    lines += ["M30", "%"]
    path.write_text("\n".join(lines) + "\n")


def _peak_and_rows(src, out, chunk_size):
    def corr():
        for c in iter_segment_chunks(src, XFYZ, chunk_size=chunk_size):
            shift = np.zeros_like(c.end)
            shift[:, 2] = 1e-3                       # a correction: every end 1 um higher
            yield c, c.end + shift, np.ones(len(c), np.int64)
    tracemalloc.start()
    try:
        rows = write_corrected(src, out, XFYZ, corr())
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return peak, rows


@pytest.mark.parametrize("mode, small, large", [("compiled", 10_000, 100_000), ("python", 800, 8_000)])
def test_memory_flat_with_length(tmp_path, monkeypatch, mode, small, large):
    if mode == "python":
        monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
    elif not _fast.available():
        pytest.skip("no C compiler: the compiled G-code path is not available")
    monkeypatch.setattr(_fast, "_BLOCK", 1 << 16)     # read 64 kB at a time
    monkeypatch.setattr(_fast, "_OUT", 1 << 18)
    peaks = {}
    for n in (small, large):
        src = tmp_path / f"p{n}.nc"
        _program(src, n)
        out = tmp_path / f"o{n}.nc"
        peaks[n], rows = _peak_and_rows(src, out, chunk_size=200)
        assert rows >= n + 2
        written = out.read_text().splitlines()
        assert len(written) >= n + 6
        assert written[-2:] == ["M30", "%"]
    size_large = (tmp_path / f"p{large}.nc").stat().st_size
    # ten times the program, about the same peak; far below the size of the program itself
    assert peaks[large] < 1.3 * peaks[small] + 200_000
    if mode == "compiled":
        assert peaks[large] < 0.5 * size_large
