"""The package's import graph: no module imports one above it in the pipeline, and no import cycle.

The pipeline, lowest first (a module may import its own level and those below):
errors, io -> machine, kinematics -> models -> measurement -> identification, sim -> diagnose,
thermal (thermal uses diagnose's result types; diagnose never imports thermal) -> planner ->
toolpaths, viz, export, compensation -> study, commands, demo, cli.

Read from the source with :mod:`ast` (every import statement, also those inside functions), so a
lazy import counts like any other.

And the size of the code: no module over ``MAX_MODULE_LINES`` lines, no function (or method) over
``MAX_FUNCTION_LINES`` lines unless a comment within its first 5 lines says why ("long because ...").
"""
from __future__ import annotations

import ast
from pathlib import Path

import mtcomp

PACKAGE = Path(mtcomp.__file__).resolve().parent

LEVELS = {"errors": 0, "io": 0, "_threads": 0, "machine": 1, "kinematics": 1, "models": 2, "measurement": 3,
          "identification": 4, "sim": 4, "diagnose": 5, "thermal": 5, "planner": 6, "toolpaths": 7,
          "viz": 7, "export": 7, "compensation": 7, "_compensation_notes": 7, "study": 8, "commands": 8, "demo": 8, "cli": 8, "__main__": 8, "": 8}
#: imports within one level that may go one way only
ONE_WAY = {("thermal", "diagnose")}
#: what the package still does against these rules, each with the reason it is left (a new one fails)
KNOWN_UPWARD: dict = {}
KNOWN_CYCLES: list = []
#: the layers of the G-code reader and writer in mtcomp.toolpaths, lowest first (gcode is the
#: public face: it re-exports them and chooses the compiled or the Python path)
GCODE_LAYERS = ["words", "blocks", "modal", "reader", "writer", "_fast", "gcode"]
#: the size limits: lines of a module, lines of a function from its ``def`` to its last line
MAX_MODULE_LINES = 800
MAX_FUNCTION_LINES = 80
#: functions still over the limit with no comment, each with the reason it is left (a new one
#: fails; when one is split, remove it from here)
KNOWN_LONG: dict = {}


def _modules() -> dict:
    out = {}
    for f in PACKAGE.rglob("*.py"):
        parts = ("mtcomp",) + f.relative_to(PACKAGE).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = f
    return out


def _edges(mods: dict) -> dict:
    """module -> set of mtcomp modules it imports (a name imported from a package that is a
    submodule counts as that submodule)."""
    edges = {}
    for m, f in mods.items():
        pkg = m if f.name == "__init__.py" else m.rsplit(".", 1)[0]
        targets = set()
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = pkg
                for _ in range(max(node.level - 1, 0)):
                    base = base.rsplit(".", 1)[0]
                target = (f"{base}.{node.module}" if node.module else base) if node.level else node.module
                subs = [f"{target}.{a.name}" for a in node.names if f"{target}.{a.name}" in mods]
                names = subs + ([target] if len(subs) < len(node.names) else [])
            else:
                continue
            for t in names:
                if not t or not (t == "mtcomp" or t.startswith("mtcomp.")):
                    continue
                while t not in mods and "." in t:
                    t = t.rsplit(".", 1)[0]
                if t != m:
                    targets.add(t)
        edges[m] = targets
    return edges


def _area(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def _cycles(edges: dict) -> list:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(comp)

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def _upward(edges: dict) -> set:
    """(area, area it imports, module, module) of every import against the pipeline."""
    upward = set()
    for a, targets in edges.items():
        for b in targets:
            x, y = _area(a), _area(b)
            if x == y:
                continue
            if LEVELS[y] > LEVELS[x] or (LEVELS[y] == LEVELS[x] and (y, x) in ONE_WAY):
                upward.add((x, y, a, b))
    return upward


def _against_layers(edges: dict, package: str, layers: list) -> list:
    """'a -> b' for every import of a module of ``layers`` by one at its level or below it."""
    rank = {f"{package}.{m}": i for i, m in enumerate(layers)}
    return sorted(f"{a} -> {b}" for a in rank for b in edges.get(a, ()) if rank.get(b, -1) >= rank[a])


def test_no_module_imports_one_above_it_in_the_pipeline():
    mods = _modules()
    assert set(map(_area, mods)) <= set(LEVELS), set(map(_area, mods)) - set(LEVELS)
    upward = _upward(_edges(mods))
    new = sorted(u for u in upward if (u[0], u[1]) not in KNOWN_UPWARD)
    assert not new, "imports against the pipeline: " + "; ".join(f"{a} -> {b}" for _, _, a, b in new)
    # the known exceptions are still there (when one is fixed, remove it from the list)
    assert {(x, y) for x, y, _, _ in upward} == set(KNOWN_UPWARD)


def test_no_import_cycle_beyond_the_known_ones():
    cycles = _cycles(_edges(_modules()))
    new = [c for c in cycles if c not in KNOWN_CYCLES]
    assert not new, f"import cycles: {new}"
    assert all(c in cycles for c in KNOWN_CYCLES), "a known cycle is gone: remove it from KNOWN_CYCLES"


def test_the_gcode_layers_import_only_those_below_them():
    edges = _edges(_modules())
    assert all(f"mtcomp.toolpaths.{m}" in edges for m in GCODE_LAYERS)
    bad = _against_layers(edges, "mtcomp.toolpaths", GCODE_LAYERS)
    assert not bad, "G-code layers importing one at or above their level: " + "; ".join(bad)


def test_the_checker_sees_a_cycle_and_an_upward_import():
    """The checks can fail: a hand-made graph with a cycle and an import against the pipeline."""
    edges = {"mtcomp.models.a": {"mtcomp.models.b"}, "mtcomp.models.b": {"mtcomp.models.a"},
             "mtcomp.machine": {"mtcomp.planner.engine"}, "mtcomp.planner.engine": set()}
    assert _cycles(edges) == [{"mtcomp.models.a", "mtcomp.models.b"}]
    edges["mtcomp.diagnose.x"] = {"mtcomp.thermal.y"}        # one way only: thermal -> diagnose
    edges["mtcomp.thermal.y"] = {"mtcomp.diagnose.x"}
    assert {(x, y) for x, y, _, _ in _upward(edges)} == {("machine", "planner"), ("diagnose", "thermal")}
    layered = {"p.words": set(), "p.modal": {"p.words", "p.reader"}, "p.reader": {"p.modal"}}
    assert _against_layers(layered, "p", ["words", "modal", "reader"]) == ["p.modal -> p.reader"]


def _long_functions(source: str, limit: int = MAX_FUNCTION_LINES) -> list:
    """(name, lines) of every function of ``source`` longer than ``limit`` lines whose first 5
    lines hold no comment saying "long because"."""
    lines = source.splitlines()
    out = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        n = node.end_lineno - node.lineno + 1
        head = lines[node.lineno - 1:node.lineno + 4]
        said = any(line.strip().startswith("#") and "long because" in line for line in head)
        if n > limit and not said:
            out.append((node.name, n))
    return out


def test_no_module_over_the_size_limit():
    sizes = {str(f.relative_to(PACKAGE)): len(f.read_text(encoding="utf-8").splitlines())
             for f in PACKAGE.rglob("*.py")}
    big = sorted(f"{f} ({n} lines)" for f, n in sizes.items() if n > MAX_MODULE_LINES)
    assert not big, f"modules over {MAX_MODULE_LINES} lines: " + "; ".join(big)


def test_no_function_over_the_size_limit_without_a_reason():
    found = {}
    for f in PACKAGE.rglob("*.py"):
        for name, n in _long_functions(f.read_text(encoding="utf-8")):
            found[f"{f.relative_to(PACKAGE).as_posix()}:{name}"] = n
    new = sorted(f"{k} ({n} lines)" for k, n in found.items() if k not in KNOWN_LONG)
    assert not new, (f"functions over {MAX_FUNCTION_LINES} lines (split them, or say in a comment in "
                     "their first 5 lines why they are long): " + "; ".join(new))
    gone = sorted(set(KNOWN_LONG) - set(found))
    assert not gone, "no longer over the limit: remove from KNOWN_LONG: " + "; ".join(gone)


def test_the_size_checker_sees_a_long_function():
    """The check can fail: a hand-made function of 81 lines is found, of 80 lines or with its reason
    in a comment is not; methods count too."""
    def source(n_body, comment=None, indent=""):
        head = [f"{indent}def f():"] + ([f"{indent}    # {comment}"] if comment else [])
        return "\n".join(head + [f"{indent}    x = {i}" for i in range(n_body - len(head))]) + "\n"
    assert _long_functions(source(81)) == [("f", 81)]
    assert _long_functions(source(80)) == []
    assert _long_functions(source(81, "long because one table of cases")) == []
    assert _long_functions(source(81, "long, no reason")) == [("f", 81)]
    assert _long_functions("class C:\n" + source(90, indent="    ")) == [("f", 90)]
    # the reason must be a comment, in the first 5 lines
    late = source(81).replace("    x = 6\n", "    # long because too late\n")
    assert _long_functions(late) == [("f", 81)]
