"""``mtcomp demo [--out DIR]``: the whole job on built-in defaults (docs/demo.md)."""
from __future__ import annotations


def add_arguments(parser):
    parser.add_argument("--out", default="mtcomp-demo", metavar="DIR",
                        help="folder for every file the demo writes (default ./mtcomp-demo; created "
                             "if needed; nothing outside it is written)")
    parser.add_argument("--seed", type=int, default=2026,
                        help="random seed of the virtual machine (truth and noise)")


def run(args) -> int:
    from pathlib import Path

    from ..demo import format_table, run_demo
    from ..errors import InputError

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError("--out must be a folder, and this is a file", out)
    if not out.resolve().parent.is_dir():
        raise InputError(f"the parent folder {out.resolve().parent} does not exist", out)
    res = run_demo(out, seed=args.seed, say=lambda s: print(s, flush=True))
    print()
    print("summary")
    print(format_table(res.table))
    print()
    print(f"files in {out}/: " + ", ".join(f for f in res.files if not f.startswith("campaign/"))
          + f", campaign/ ({sum(f.startswith('campaign/') for f in res.files)} CSV files)")
    print(f"total {res.seconds:.1f} s")
    return 0
