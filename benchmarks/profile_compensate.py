"""Where a compensation's time goes: seconds per stage of one ``mtcomp compensate`` run.

    PYTHONPATH=. python benchmarks/profile_compensate.py [--blocks 1280000] [--report]
        [--program IN.nc] [--model MODEL.json | --synthetic] [--machine xfyz]
        [-- extra compensate flags, e.g. --max-correction-sd-um 0]

Runs the compensation in this process, with one planner thread (``MTCOMP_THREADS=1``: every stage
on the main thread, so that the stages add up), on bench_compensate_copy.py's program and model
(identified as ``mtcomp demo`` does, bench_compensate.py's ``write_identified_model``; with
``--synthetic`` its synthetic base model, which no user has) unless ``--program`` and ``--model``
are given. Stage times are wall seconds; the CPU seconds of the whole run are printed too (on a
loaded machine wall time overstates). Each stage is the inclusive time of the functions
named in ``STAGES`` (a stage called inside another is subtracted from it, see ``_Clock``); what no
stage claims is "planner (rest)". The import of what compensate uses is timed before it. The
checkout profiled is the one on PYTHONPATH (``PYTHONPATH=/other/checkout:benchmarks`` profiles
another).
"""
from __future__ import annotations

import argparse
import importlib
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

#: stage -> (module, qualified name) of the functions timed as that stage
STAGES = {
    "read+write scan (C)": [("mtcomp.toolpaths._fast", "_Driver.call"),
                            ("mtcomp.toolpaths._fast", "_Driver.fill")],
    "modal (Python lines)": [("mtcomp.toolpaths._fast", "_Driver.fallback")],
    "format (Python lines)": [("mtcomp.toolpaths._fast", "format_motion_lines"),
                              ("mtcomp.toolpaths._fast", "write_pass_through")],
    "pose/datum (setup)": [("mtcomp.toolpaths.offsets", "ProgramSetup.apply")],
    "sd gate": [("mtcomp.planner.engine", "Planner._sd_um")],
    "model evaluation": [("mtcomp.planner._evaluate", "evaluate")],
    "nominal kinematics": [("mtcomp.planner._evaluate", "nominal_pose"),
                           ("mtcomp.planner._evaluate", "nominal_pose_jacobian")],
    "osqp solve": [("mtcomp.planner._qp", "WindowQP.solve")],
    # OSQP's set-up of a window size, and the import of osqp and scipy.sparse the first one does
    "osqp setup+import": [("mtcomp.planner._qp", "WindowQP.__init__")],
    "report rows": [("mtcomp.compensation", "_report_lines"),
                    ("mtcomp.compensation", "report_rows")],
    # the planner's own numpy, stage by stage (what the model evaluation and the nominal
    # kinematics inside them take is counted above, not here)
    "newton (numpy)": [("mtcomp.planner.engine", "solve_newton"),
                       ("mtcomp.planner.engine", "solve_pinv")],
    "residual assembly": [("mtcomp.planner._evaluate", "Evaluator.residual"),
                          ("mtcomp.planner._evaluate", "Evaluator.residual_jacobian")],
    "datum reference": [("mtcomp.planner.engine", "Planner._reference")],
    "block context": [("mtcomp.planner.engine", "Planner._context")],
    "subdivide (numpy)": [("mtcomp.planner.engine", "Planner._subdivide")],
    "nodes (numpy)": [("mtcomp.planner.engine", "Planner.nodes_from_chunk")],
    "bounds enforce": [("mtcomp.planner._bounds", "Bounds.enforce")],
    "commit (numpy)": [("mtcomp.planner.engine", "Planner._commit")],
    "windows (numpy)": [("mtcomp.planner.engine", "Planner.plan_nodes")],
    "results join": [("mtcomp.planner.engine", "PlanResult.concatenate"),
                     ("mtcomp.planner.engine", "PlanResult.take")],
    "summary+tally": [("mtcomp.planner.report", "Summary.add"),
                      ("mtcomp.compensation", "_Tally.planned"),
                      ("mtcomp.compensation", "_to_program_frame")],
}


class _Clock:
    """Inclusive time per stage, less the time of stages called inside it (a stack of starts)."""

    def __init__(self):
        self.total: dict[str, float] = {}
        self.stack: list[list] = []

    def wrap(self, stage, fn):
        def timed(*a, **k):
            self.stack.append([stage, 0.0])
            t = time.perf_counter()
            try:
                out = fn(*a, **k)
            finally:
                dt = time.perf_counter() - t
                _, inner = self.stack.pop()
                self.total[stage] = self.total.get(stage, 0.0) + dt - inner
                if self.stack:
                    self.stack[-1][1] += dt
            return out
        return timed


def _install(clock: _Clock) -> None:
    for stage, names in STAGES.items():
        for module, qual in names:
            mod = importlib.import_module(module)
            owner, attr = mod, qual
            if "." in qual:
                cls, attr = qual.split(".")
                owner = getattr(mod, cls)
            if hasattr(owner, attr):        # an older checkout may not have it
                setattr(owner, attr, clock.wrap(stage, getattr(owner, attr)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=1_280_000)
    ap.add_argument("--program")
    ap.add_argument("--model")
    ap.add_argument("--synthetic", action="store_true",
                    help="bench_compensate.py's synthetic base model instead of an identified one")
    ap.add_argument("--machine", default="xfyz")
    ap.add_argument("--report", action="store_true")
    ap.add_argument("extra", nargs="*")
    args = ap.parse_args(argv)
    os.environ["MTCOMP_THREADS"] = "1"
    t0 = time.perf_counter()
    import casadi  # noqa: F401

    import mtcomp.commands.compensate  # noqa: F401
    import mtcomp.compensation  # noqa: F401
    t_import = time.perf_counter() - t0
    from mtcomp.cli import main as cli
    clock = _Clock()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        prog, model = args.program, args.model
        if prog is None:
            from bench_gcode import make_program
            prog = tmp / "p.nc"
            make_program(prog, args.blocks)
        if model is None:
            from bench_compensate import write_identified_model_apart, write_model
            model = tmp / "m.json"
            if args.synthetic:
                write_model(model, args.machine)
            else:
                write_identified_model_apart(model)
        cmd = ["compensate", args.machine, str(model), str(prog), "-o", str(tmp / "out.nc"),
               "--quiet", *args.extra]
        if args.report:
            cmd += ["--report", str(tmp / "blocks.csv")]
        _install(clock)
        t1, c1 = time.perf_counter(), time.process_time()
        code = cli(cmd)
        wall, cpu = time.perf_counter() - t1, time.process_time() - c1
    print(f"exit {code}; import {t_import:.2f} s; compensate {wall:.2f} s wall, {cpu:.2f} s CPU; "
          f"peak {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB",
          file=sys.stderr)
    claimed = 0.0
    for stage, s in sorted(clock.total.items(), key=lambda kv: -kv[1]):
        print(f"  {stage:24s} {s:7.2f} s", file=sys.stderr)
        claimed += s
    print(f"  {'planner (rest)':24s} {wall - claimed:7.2f} s", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
