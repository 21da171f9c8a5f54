"""Planner fast paths give the plan of the plain paths: the per-block normal equations against
numpy's dense solve, feasible runs of windows against window-by-window planning, threads against
one thread, the read-ahead thread against plain iteration."""
import sys

import numpy as np
import pytest

from mtcomp.models import PeriodicError
from mtcomp.planner import CompensationProblem, Planner, PlannerOptions, output_grid, plan_chunks
from mtcomp.planner import _parallel
from mtcomp.planner._small import NormalFactor, normal_step, row_max_abs, row_norm
from mtcomp.toolpaths.gcode import SegmentChunk

from test_planner_core import _segment_chunk, fitted_model


@pytest.mark.parametrize("rows,cols", [(3, 3), (6, 5), (6, 6), (3, 5)])
def test_normal_step_matches_a_dense_solve(rows, cols):
    rng = np.random.default_rng(rows * 10 + cols)
    n, lam = 50, 1e-3
    A = rng.normal(size=(n, rows, cols))
    b = rng.normal(size=(n, rows))
    x = rng.normal(size=(n, cols))
    H = np.einsum("nki,nkj->nij", A, A) + lam * np.eye(cols)
    g = np.einsum("nki,nk->ni", A, b) + lam * x
    want = -np.linalg.solve(H, g[:, :, None])[:, :, 0]
    np.testing.assert_allclose(normal_step(A, b, x, lam), want, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(normal_step(A, b, None, lam),
                               -np.linalg.solve(H, (g - lam * x)[:, :, None])[:, :, 0],
                               rtol=1e-9, atol=1e-9)
    # kept factors: a second right-hand side, and a subset of the blocks, give the same numbers
    f = NormalFactor(A, lam)
    b2 = rng.normal(size=(n, rows))
    np.testing.assert_array_equal(f.step(b2, x), normal_step(A, b2, x, lam))
    keep = rng.random(n) < 0.5
    np.testing.assert_array_equal(f.take(keep).step(b2[keep], x[keep]), f.step(b2, x)[keep])


def test_row_reductions_match_numpy():
    a = np.random.default_rng(3).normal(size=(40, 5))
    np.testing.assert_array_equal(row_max_abs(a), np.max(np.abs(a), axis=1))
    np.testing.assert_array_equal(row_norm(a), np.sqrt(np.sum(a ** 2, axis=1)))


def _bounded_stream(seed, n=600):
    """A path whose free corrections (17 to 19.6 um) exceed a 19 um bound along part of it only:
    some windows keep every bound with their unbounded solution, others need OSQP."""
    fitted = fitted_model("xfyz", seed)
    m = fitted.machine
    t = np.linspace(0.0, 1.0, n + 1)
    pts = np.stack([-200 + 400 * t, 100 * np.sin(5 * t), -40 + 30 * t], axis=1)
    problem = CompensationProblem.from_machine(fitted, max_correction_um=19.0, max_step_um=0.3,
                                               grid=output_grid(m))
    return problem, _segment_chunk(m, pts)


@pytest.mark.parametrize("overlap", [4, 0])
def test_feasible_runs_give_the_window_by_window_plan(monkeypatch, overlap):
    problem, chunk = _bounded_stream(91)
    opts = PlannerOptions(window=16, overlap=overlap, subdivide_tol_um=None, threads=1)
    planner = Planner(problem, opts)
    committed = []
    real_run = Planner._feasible_run

    def spy(self, *args):
        res, n = real_run(self, *args)
        committed.append(n)
        return res, n

    monkeypatch.setattr(Planner, "_feasible_run", spy)
    (_, fast), = list(planner.iter_chunks([chunk]))
    runs = planner.stats
    assert sum(committed) >= 4 * opts.window       # runs of windows were committed at once
    monkeypatch.setattr(Planner, "_feasible_run", lambda self, *a: (None, 0))
    slow_planner = Planner(problem, opts)
    (_, slow), = list(slow_planner.iter_chunks([chunk]))
    # both paths ran: some windows in runs, some with OSQP, and the same windows were counted
    assert 0 < runs["windows_qp"] < runs["windows"]
    assert runs["windows"] == slow_planner.stats["windows"]
    assert runs["windows_qp"] == slow_planner.stats["windows_qp"]
    assert slow.flags.any()
    for f in ("corrected", "after", "flags", "iterations"):
        np.testing.assert_array_equal(getattr(fast, f), getattr(slow, f))


@pytest.mark.parametrize("window,overlap,size", [(16, 4, 37), (100, 0, 150), (7, 30, 333)])
def test_streamed_batches_give_the_plan_of_the_whole(window, overlap, size):
    """Windows that start in the nodes kept from the last batch are planned on those joined with
    only the first new nodes they need: the same corrections as planning everything at once."""
    problem, whole = _bounded_stream(91, n=1200)
    opts = PlannerOptions(window=window, overlap=overlap, subdivide_tol_um=None, threads=1)
    (_, ref), = list(plan_chunks(problem, [whole], opts))
    parts = [SegmentChunk(*(getattr(whole, f)[a:a + size] for f in
                            ("line", "start", "end", "feed", "dirs", "rapid", "from_arc")))
             for a in range(0, len(whole), size)]
    got = list(plan_chunks(problem, parts, opts))
    assert ref.flags.any() and not ref.flags.all()
    for f in ("corrected", "flags", "after"):
        np.testing.assert_array_equal(np.concatenate([getattr(r, f) for _, r in got]), getattr(ref, f))


def test_threads_give_the_plan_of_one_thread(monkeypatch):
    """Chunks cut into parts for threads (tiny parts here), internal nodes, planning ahead."""
    fitted = fitted_model("xfyz", 71, [PeriodicError("X", 40.0)])
    fitted.params["PER_X_c"] = 3e-3
    m = fitted.machine
    t = np.linspace(0.0, 1.0, 31)       # moves of ~13 mm: the 40 mm period needs internal nodes
    pts = np.stack([-200 + 400 * t, 100 * np.cos(3 * t), -30 + 20 * t], axis=1)
    pts[20:, 0] = pts[20, 0]        # a stretch along Y only
    whole = _segment_chunk(m, pts)
    parts = [SegmentChunk(*(getattr(whole, f)[a:a + 12] for f in
                            ("line", "start", "end", "feed", "dirs", "rapid", "from_arc")))
             for a in range(0, 30, 12)]
    problem = CompensationProblem.from_machine(fitted, max_correction_um=8.0, max_step_um=0.5,
                                               grid=output_grid(m))
    plans = {}
    for threads in (1, 3):
        monkeypatch.setattr(_parallel, "MIN_PART", 4)
        out = list(plan_chunks(problem, parts, PlannerOptions(window=32, overlap=8, threads=threads)))
        assert [c is p for (c, _), p in zip(out, parts)] == [True] * len(parts)
        plans[threads] = out
    inserted = sum(int(r.inserted.sum()) for _, r in plans[1])
    assert inserted > 0
    for (_, a), (_, b) in zip(plans[1], plans[3]):
        for f in ("corrected", "after", "flags", "counts"):
            np.testing.assert_array_equal(getattr(a, f), getattr(b, f))


def test_read_ahead_keeps_order_raises_in_place_and_stops_when_closed():
    assert list(_parallel.read_ahead(iter(range(50)), depth=2)) == list(range(50))

    def failing():
        yield 1
        yield 2
        raise ValueError("bad block")

    got = []
    with pytest.raises(ValueError, match="bad block"):
        for v in _parallel.read_ahead(failing()):
            got.append(v)
    assert got == [1, 2]

    made = []

    def endless():
        k = 0
        while True:
            made.append(k)
            yield k
            k += 1

    gen = _parallel.read_ahead(endless(), depth=1)
    assert [next(gen) for _ in range(3)] == [0, 1, 2]
    gen.close()                     # joins the thread: it stops within depth + 1 items
    assert len(made) <= 3 + 2


def test_split_rows_joins_parts_in_order(monkeypatch):
    monkeypatch.setattr(_parallel, "MIN_PART", 3)
    a = np.arange(20.0)
    parts = _parallel.split_rows(lambda v: v * 2.0, a.size, 4, a)
    assert len(parts) == 4
    np.testing.assert_array_equal(np.concatenate(parts), a * 2.0)
    assert len(_parallel.split_rows(lambda v: v, 5, 4, a[:5])) == 1


def test_thread_count_from_the_option_or_the_environment(monkeypatch):
    monkeypatch.setenv("MTCOMP_THREADS", "3")
    assert _parallel.resolve_threads(0) == 3
    assert _parallel.resolve_threads(2) == 2
    monkeypatch.setenv("MTCOMP_THREADS", "many")
    assert _parallel.resolve_threads(0) == max(1, min(4, _parallel.available_threads()))
    with pytest.raises(ValueError):
        PlannerOptions(threads=-1)


@pytest.mark.parametrize("text,want", [("G21 G90\nG1 X1\n", False), ("g20\n", True),
                                       ("G1 X20 G201\n", False), ("N5 G0020 X1\n", True),
                                       ("G020.5\n", False), ("(metric) G21\nG1 X1 ; G20\n", True)])
def test_uses_inches_finds_g20_words_across_read_blocks(tmp_path, text, want):
    from mtcomp.compensation import uses_inches
    path = tmp_path / "p.nc"
    path.write_text("G1 X1.0000 Y2.0000\n" * 7 + text + "G1 X3\n" * 5)
    for block in (9, 10, 11, 13, 1 << 22):      # a word cut at every place between two reads
        assert uses_inches(path, block=block) is want


@pytest.mark.parametrize("threads", [1, 2])
def test_ctrl_c_inside_osqp_stops_the_plan(monkeypatch, threads):
    """OSQP traps SIGINT during a solve and returns its iterate with the status 'interrupted': the
    planner raises KeyboardInterrupt (the command exits 130 and writes nothing), from the planning
    thread too, instead of planning on with that iterate."""
    import types

    import osqp
    problem, chunk = _bounded_stream(91)

    def interrupted(self, *args, **kwargs):
        info = types.SimpleNamespace(status="interrupted", status_val=10, iter=7)
        return types.SimpleNamespace(x=np.zeros(self.n if hasattr(self, "n") else 0), info=info)

    monkeypatch.setattr(osqp.OSQP, "solve", interrupted)
    planner = Planner(problem, PlannerOptions(window=16, subdivide_tol_um=None, threads=threads))
    with pytest.raises(KeyboardInterrupt):
        list(planner.iter_chunks([chunk]))


def test_a_window_osqp_does_not_converge_on_is_solved_by_the_interior_point_method(monkeypatch):
    """Where OSQP stops at its iteration limit (a user's 2,011-block window under a backlash's
    reversal rule took 245 s to 'solved inaccurate'), the window's QP goes to Clarabel: the same
    plan as OSQP's converged one (a second solver as the oracle), not the clamped fallback."""
    from mtcomp.planner import _qp
    problem, chunk = _bounded_stream(91)
    opts = PlannerOptions(window=16, overlap=4, subdivide_tol_um=None, threads=1)
    (_, ref), = list(Planner(problem, opts).iter_chunks([chunk]))
    calls = []
    real = _qp.interior_point_solve

    def spy(*args):
        calls.append(args[0].shape[0])
        return real(*args)

    monkeypatch.setattr(_qp, "OSQP_MAX_ITER", 2)          # OSQP never converges in 2 iterations
    monkeypatch.setattr(_qp, "interior_point_solve", spy)
    planner = Planner(problem, opts)
    (_, got), = list(planner.iter_chunks([chunk]))
    assert len(calls) == planner.stats["qp_solves"] > 0
    assert "qp_failed" not in planner.stats
    # the same corrections up to the output grid's last digit where a bound is not active
    np.testing.assert_allclose(got.corrected, ref.corrected, rtol=0, atol=2.01e-4)
    np.testing.assert_array_equal(got.flags, ref.flags)


def test_interior_point_solve_matches_osqp_on_a_small_bounded_qp():
    """The interior-point solve of OSQP's problem form (two-sided rows, equalities, absent bounds)
    against OSQP's converged solution of the same random QP."""
    import osqp
    import scipy.sparse as sp

    from mtcomp.planner._bounds import INF
    from mtcomp.planner._qp import interior_point_solve
    rng = np.random.default_rng(5)
    n, m = 12, 20
    G = rng.normal(size=(n, n))
    P = sp.csc_matrix(G @ G.T + np.eye(n))
    q = rng.normal(size=n)
    A = sp.csc_matrix(rng.normal(size=(m, n)))
    lower, upper = -rng.uniform(0.1, 1, m), rng.uniform(0.1, 1, m)
    lower[:3], upper[3:6], upper[6], lower[6] = -INF, INF, 0.2, 0.2      # one-sided rows, an equality
    x, status = interior_point_solve(sp.triu(P, format="csc"), q, A, lower, upper)
    s = osqp.OSQP()
    s.setup(sp.triu(P, format="csc"), q, A, lower, upper, verbose=False, eps_abs=1e-10,
            eps_rel=1e-10, polishing=True, max_iter=200000)
    ref = s.solve()
    assert status == "solved" and ref.info.status == "solved"
    np.testing.assert_allclose(x, ref.x, rtol=0, atol=1e-6)


def test_a_long_program_planned_with_threads_imports_osqp_before_its_first_qp(monkeypatch):
    """With CPUs to spare, a program of more than one chunk has OSQP imported in a thread of its
    own from its second chunk on (its first window that needs the QP no longer waits for the
    import); a one-chunk program, one planning thread or another method import nothing ahead."""
    import threading

    from mtcomp.planner import _qp, engine
    problem, chunk = _bounded_stream(91, n=60)
    parts = [SegmentChunk(*(getattr(chunk, f)[a:a + 20] for f in
                            ("line", "start", "end", "feed", "dirs", "rapid", "from_arc")))
             for a in range(0, 60, 20)]
    calls, read = [], []

    def source(chunks):
        for c in chunks:
            read.append(c)
            yield c

    monkeypatch.setattr(engine, "prefetch_solver", lambda: calls.append(len(read)))
    for parts_, threads, method, want in ((parts, 2, "qp", [2]), (parts[:1], 2, "qp", []),
                                          (parts, 1, "qp", []), (parts, 2, "pinv", [])):
        calls.clear()
        read.clear()
        opts = PlannerOptions(window=16, subdivide_tol_um=None, threads=threads, method=method)
        out = list(Planner(problem, opts).iter_chunks(source(parts_)))
        assert [c for c, _ in out] == parts_
        assert calls == want, (len(parts_), threads, method)     # as the second chunk is planned
    # the thread itself: imports OSQP; a failed import raises nothing there (the QP's set-up does)
    import builtins
    real_import = builtins.__import__

    def no_osqp(name, *args, **kwargs):
        if name == "osqp":
            raise ImportError("no osqp here")
        return real_import(name, *args, **kwargs)

    for importer in (no_osqp, real_import):
        failed = []
        with monkeypatch.context() as m:
            for name in [k for k in sys.modules if k == "osqp" or k.startswith("osqp.")]:
                m.delitem(sys.modules, name)
            m.setattr(_qp, "_prefetching", False)
            m.setattr(builtins, "__import__", importer)
            m.setattr(threading, "excepthook", lambda args: failed.append(args.exc_type))
            _qp.prefetch_solver()
            for t in threading.enumerate():
                if t.name == "mtcomp-import-qp":
                    t.join(timeout=60)
            assert failed == []
            assert ("osqp" in sys.modules) is (importer is real_import)
