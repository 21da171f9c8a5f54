"""Byte-compare what two checkouts of mtcomp write from ``compensate``: the speed work's safety net.

    PYTHONPATH=.:tests python benchmarks/compare_compensate_outputs.py inputs DIR [--blocks 1280000]
    python benchmarks/compare_compensate_outputs.py run CHECKOUT DIR OUT_A
    python benchmarks/compare_compensate_outputs.py run OTHER_CHECKOUT DIR OUT_B
    python benchmarks/compare_compensate_outputs.py cmp OUT_A OUT_B

``inputs`` writes, once, the programs and models both checkouts read: bench_compensate_copy.py's
program with its identified model (as ``mtcomp demo`` identifies it: splines, a covariance, a
support region) and with the synthetic one, the demo's bowl with the identified model, and every program of tests/data/gcode_corpus with the machine and model the
corpus test gives it (tests/test_gcode_corpus.py). ``run`` compensates each of them in a fresh
subprocess of CHECKOUT (``python -m mtcomp`` run from that folder, so it imports that checkout),
twice: with the default settings and with ``--report``; it keeps the output program, the report,
the exit status, stdout and stderr. ``cmp`` compares two such folders file by file and prints the
files that differ (exit 1 when any does).
"""
from __future__ import annotations

import argparse
import filecmp
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

CORPUS = Path(__file__).resolve().parent.parent / "tests" / "data" / "gcode_corpus"


def make_inputs(folder: Path, blocks: int) -> None:
    """The programs, machines and models of every case, and cases.json listing them."""
    from bench_compensate import write_identified_model, write_model
    from bench_gcode import make_program

    from mtcomp.demo import write_bowl
    from test_gcode_corpus import BORING_MILLS, PROGRAMS, _machine_file, _model_file, _topology
    folder.mkdir(parents=True, exist_ok=True)
    make_program(folder / "bench.nc", blocks)
    write_model(folder / "bench_model.json", "xfyz")
    cases = [{"name": "bench", "machine": "xfyz", "model": "bench_model.json",
              "program": "bench.nc", "extra": []}]
    write_identified_model(folder / "identified_model.json")
    write_bowl(folder / "bowl.nc")
    cases += [{"name": name, "machine": "xfyz", "model": "identified_model.json",
               "program": prog, "extra": []}
              for name, prog in (("bench_identified", "bench.nc"), ("bowl_identified", "bowl.nc"))]
    models = {}
    for prog in PROGRAMS:
        topology = _topology(prog.read_text(encoding="latin-1"))
        key = (topology, prog.name in BORING_MILLS)     # a boring mill's W quill, declared
        if key not in models:
            sub = folder / (topology.lower() + ("_quill" if key[1] else ""))
            sub.mkdir(exist_ok=True)
            machine = _machine_file(sub, topology, quill=key[1])
            models[key] = (str(machine.relative_to(folder)),
                           str(_model_file(sub, machine).relative_to(folder)))
        machine, model = models[key]
        shutil.copyfile(prog, folder / prog.name)
        cases.append({"name": prog.name, "machine": machine, "model": model, "program": prog.name,
                      "extra": ["--units", "mm"]})
    (folder / "cases.json").write_text(json.dumps(cases, indent=1))


def run_cases(checkout: Path, inputs: Path, out: Path) -> None:
    """Compensate every case with `checkout`'s mtcomp, default settings and with --report."""
    out.mkdir(parents=True, exist_ok=True)
    cases = json.loads((inputs / "cases.json").read_text())
    for case in cases:
        machine = case["machine"]
        machine = str(inputs / machine) if machine.endswith(".toml") else machine
        for variant in ("default", "report"):
            stem = out / f"{case['name']}.{variant}"
            cmd = [sys.executable, "-m", "mtcomp", "compensate", machine,
                   str(inputs / case["model"]), str(inputs / case["program"]),
                   "-o", f"{stem}.out", "--quiet", *case["extra"]]
            if variant == "report":
                cmd += ["--report", f"{stem}.csv"]
            proc = subprocess.run(cmd, cwd=checkout, capture_output=True)
            Path(f"{stem}.stdout").write_bytes(proc.stdout)
            Path(f"{stem}.stderr").write_bytes(proc.stderr)
            Path(f"{stem}.status").write_text(f"{proc.returncode}\n")
        print(case["name"], proc.returncode, flush=True)


def _stdout(path: Path) -> bytes:
    """What compensate printed, less what differs from run to run: the seconds on its first line
    and the folder the outputs were written to."""
    text = path.read_bytes().replace(str(path.parent).encode(), b"OUT")
    return re.sub(rb"^(mtcomp compensate: .*), [0-9.]+ s\n", rb"\1\n", text, count=1)


def _same(a: Path, b: Path) -> bool:
    if not (a.exists() and b.exists()):
        return False
    if a.suffix == ".stdout":
        return _stdout(a) == _stdout(b)
    return filecmp.cmp(a, b, shallow=False)


def compare(a: Path, b: Path) -> int:
    names = sorted({p.name for p in a.iterdir()} | {p.name for p in b.iterdir()})
    differ = [n for n in names if not _same(a / n, b / n)]
    for n in differ:
        print("differs:", n)
    print(f"{len(names) - len(differ)} of {len(names)} files identical")
    return 1 if differ else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="what", required=True)
    p = sub.add_parser("inputs")
    p.add_argument("folder", type=Path)
    p.add_argument("--blocks", type=int, default=1_280_000)
    p = sub.add_parser("run")
    p.add_argument("checkout", type=Path)
    p.add_argument("inputs", type=Path)
    p.add_argument("out", type=Path)
    p = sub.add_parser("cmp")
    p.add_argument("a", type=Path)
    p.add_argument("b", type=Path)
    args = ap.parse_args(argv)
    if args.what == "inputs":
        make_inputs(args.folder, args.blocks)
        return 0
    if args.what == "run":
        run_cases(args.checkout.resolve(), args.inputs.resolve(), args.out.resolve())
        return 0
    return compare(args.a, args.b)


if __name__ == "__main__":
    sys.exit(main())
