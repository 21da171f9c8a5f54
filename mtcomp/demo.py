"""The whole job on built-in defaults (``mtcomp demo``): simulate, identify, diagnose, compensate,
render, and check the result against the virtual machine's truth.

1. **Simulate** a measurement campaign on the built-in ``xfyz`` machine (:mod:`mtcomp.sim`): a random
   but realistic geometric truth plus a *hidden effect* the base model cannot express (backlash of the
   X axis by default). Laser runs of every axis (positioning and angular components, three feeds, two
   Abbe arms, one fine scan) and a volumetric grid with two tool lengths
   (:func:`mtcomp.sim.campaign_plans`), written as measurement CSV files
   (docs/measurements.md).
2. **Identify** the base model ("the simulation") from the files:
   :func:`mtcomp.identification.fit.identify`.
3. **Diagnose**: what the base model gets wrong, the extension, the gain on held-out data
   (:func:`mtcomp.diagnose.diagnose`); REPORT.json and the extended MODEL.json.
4. **Part program**: the bowl of Qi and Yang (2016) (80 x 80 mm, 13.8 mm deep, ball end of radius
   3 mm), a zig-zag raster along X, so X reverses at the end of every pass.
5. **Compensate** it with the extended model, and for comparison with the base model, by the real
   ``mtcomp compensate`` command (bounded QP; BLOCKS.csv).
6. **Render** the predicted before/after error map (map.png, map.vtp), the bowl as the virtual machine
   cuts it before/after (map_cut.png, map_cut.vtp: its truth), and measure what the virtual
   machine would really cut with each program (its truth, not the fitted model).

Every file goes into the output folder; nothing outside it is written.
"""
from __future__ import annotations

import contextlib
import io
import json
import textwrap
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

DEFAULT_OUT = "mtcomp-demo"
#: the hidden effect of the default run: backlash of X, um (mean up minus mean down)
HIDDEN_BACKLASH_UM = 6.0
NOISE_UM, NOISE_URAD = 0.3, 0.5
BOWL_TOOL_RADIUS_MM = 3.0   # Qi and Yang (2016): ball-end of radius 3 mm
BOWL_RASTER_MM = 1.0        # step along and between passes (the paper's path: constant scallop)
#: the part centre (rim level) on the table: away from the axis zeros, where the errors are larger
BOWL_ORIGIN_MM = (200.0, 150.0, -100.0)


@dataclass
class DemoResult:
    """What :func:`run_demo` did. ``table``: rows (label, value) of the summary; ``files``: every file
    written, relative to ``out_dir``; ``timings``: step -> seconds."""

    out_dir: Path
    files: list = field(default_factory=list)
    table: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    hidden: dict = field(default_factory=dict)
    findings: list = field(default_factory=list)
    bowl: dict = field(default_factory=dict)
    seconds: float = 0.0


class _Steps:
    def __init__(self, say, n):
        self.say, self.n, self.k = say, n, 0
        self.t0 = time.perf_counter()
        self.timings = {}

    @contextlib.contextmanager
    def step(self, name, text):
        self.k += 1
        self.say(f"[{self.k}/{self.n}] {text} ...")
        t = time.perf_counter()
        yield
        dt = time.perf_counter() - t
        self.timings[name] = dt
        self.say(f"      done in {dt:.1f} s")


def _run_command(argv: list[str], log_path: Path) -> str:
    """Run an ``mtcomp`` command in-process; its output goes to ``log_path``. Raises on failure."""
    from .cli import main
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
        rc = main(argv)
    text = buf.getvalue()
    log_path.write_text(text, encoding="utf-8")
    if rc != 0:
        raise RuntimeError(f"mtcomp {' '.join(argv)} failed (exit {rc}):\n{text}")
    return text


def _rms_max(v):
    return float(np.sqrt(np.mean(v ** 2))), float(np.max(np.abs(v)))


def form_error(dn_um, points, normals) -> np.ndarray:
    """The normal deviations (um) less the best rigid motion of the part, ``n . (t + w x p)``, fitted
    by least squares: what is left when the part's datum is probed, as a CMM report of form shows it
    (a set-up or a rigid offset of the whole part is not a form error)."""
    n, p = np.asarray(normals, dtype=float), np.asarray(points, dtype=float)
    p = p - p.mean(axis=0)
    D = np.hstack([n, np.cross(p, n)])          # d(n . (t + w x p)) / d(t, w)
    coef, *_ = np.linalg.lstsq(D, dn_um, rcond=None)
    return dn_um - D @ coef


def write_bowl(path: Path) -> dict:
    """Write the bowl finishing program of Qi and Yang (2016)
    (:func:`mtcomp.toolpaths.parts.write_bowl_program`, ball-end of radius 3 mm as in the paper, 1 mm
    raster) to ``path``; its description."""
    from .toolpaths.parts import write_bowl_program
    tp = write_bowl_program(path, ball_radius_mm=BOWL_TOOL_RADIUS_MM, stepover_mm=BOWL_RASTER_MM,
                            step_mm=BOWL_RASTER_MM, origin_mm=BOWL_ORIGIN_MM)
    return {"size_mm": tp.side, "depth_mm": tp.depth, "tool_radius_mm": tp.ball_radius,
            "cutting_points": int(tp.tool_tips.shape[0]), "origin_mm": list(BOWL_ORIGIN_MM)}


def run_demo(out_dir=DEFAULT_OUT, seed: int = 2026, say=print) -> DemoResult:
    """Run the demo into ``out_dir`` (created if needed). ``say``: where progress lines go."""
    from .machine import load_machine

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    camp = out / "campaign"
    camp.mkdir(exist_ok=True)
    res = DemoResult(out)
    steps = _Steps(say, 6)
    machine = load_machine("xfyz")
    rng = np.random.default_rng(seed)
    with steps.step("simulate", f"simulating a measurement campaign on {machine.name} "
                    f"({machine.topology}) with a hidden effect"):
        truth, datasets = _simulate(machine, rng, camp, res, say)
    with steps.step("identify", "identifying the base model (rigid-body geometry)"):
        _identify_base(machine, datasets, out, res, say)
    with steps.step("diagnose", "diagnosing what the base model gets wrong"):
        diag, report = _diagnose_campaign(machine, datasets, out, res, say)
    bowl = out / "bowl.nc"
    with steps.step("bowl", "writing the bowl program (Qi and Yang 2016)"):
        res.bowl = write_bowl(bowl)
        res.files.append("bowl.nc")
    comp = out / "bowl_compensated.nc"
    comp_base = out / "bowl_compensated_base.nc"
    with steps.step("compensate", "compensating the bowl (mtcomp compensate, bounded QP)"):
        _compensate_bowl(out, bowl, comp, comp_base, res)
    with steps.step("render", "rendering the error map and cutting the bowl on the virtual machine"):
        _render_and_check(machine, diag, truth, out, (bowl, comp, comp_base), res)
    res.timings = steps.timings
    res.seconds = time.perf_counter() - steps.t0
    res.table = summary_rows(res, report, diag)
    return res


def _simulate(machine, rng, camp: Path, res: DemoResult, say):
    """Step 1: a measurement campaign on the virtual machine with a hidden backlash of X, written
    into ``camp``. Returns (the true model, the measurement sets)."""
    from . import sim
    from .models import Backlash
    from .sim import campaign_plans
    truth = sim.random_truth(machine, rng, terms=(Backlash("X"),))
    truth.params.set_file_value("BL_X", HIDDEN_BACKLASH_UM)
    vm = sim.VirtualMachine(machine, truth, noise_um=NOISE_UM, noise_urad=NOISE_URAD, rng=rng)
    plans = campaign_plans(machine, "small")
    data = vm.campaign(plans, camp)
    datasets = list(data.values())
    n_read = sum(len(d) for d in datasets)
    res.files += [f"campaign/{name}.csv" for name in data]
    res.hidden = {"effect": "backlash", "axis": "X", "magnitude_um": HIDDEN_BACKLASH_UM}
    say(f"      {len(datasets)} files, {n_read} readings, noise {NOISE_UM} um / {NOISE_URAD} urad "
        f"-> {camp}")
    return truth, datasets


def _identify_base(machine, datasets, out: Path, res: DemoResult, say) -> None:
    """Step 2: identify the base model (MODEL_base.json, identify.txt)."""
    from .identification.fit import identify
    from .models import save_model
    ident = identify(machine, datasets, info={"command": "mtcomp demo"})
    save_model(out / "MODEL_base.json", ident.fitted_model)
    (out / "identify.txt").write_text(ident.summary() + "\n", encoding="utf-8")
    res.files += ["MODEL_base.json", "identify.txt"]
    # the residuals' sd per unit (each unit is weighted by its own, so sigma is 1 by construction)
    resid = ", ".join(f"{v:.3g} {u}" for u, v in ident.noise.items()) or f"sigma {ident.sigma:.3g}"
    say(f"      {ident.n_params} unknowns, rank {ident.rank}, residual sd {resid} (the noise: step 1)")


def _diagnose_campaign(machine, datasets, out: Path, res: DemoResult, say):
    """Step 3: diagnose (REPORT.json, MODEL.json, diagnose.txt). Returns (diagnosis, report dict)."""
    from .diagnose import diagnose
    from .io.atomic import atomic_write
    from .models import save_model
    diag = diagnose(machine, datasets, progress=lambda s: say(f"      {s}"))
    report = diag.to_dict()
    with atomic_write(out / "REPORT.json") as f:
        json.dump(report, f, indent=1)
        f.write("\n")
    save_model(out / "MODEL.json", diag.model)
    (out / "diagnose.txt").write_text(diag.summary() + "\n", encoding="utf-8")
    res.files += ["REPORT.json", "MODEL.json", "diagnose.txt"]
    res.findings = report["findings"]
    return diag, report


def _compensate_bowl(out: Path, bowl: Path, comp: Path, comp_base: Path, res: DemoResult) -> None:
    """Step 5: compensate the bowl with the extended model (``comp``) and the base one (``comp_base``)."""
    _run_command(["compensate", "xfyz", str(out / "MODEL.json"), str(bowl), "-o", str(comp),
                  "--report", str(out / "BLOCKS.csv"), "--quiet"], out / "compensate.txt")
    _run_command(["compensate", "xfyz", str(out / "MODEL_base.json"), str(bowl), "-o",
                  str(comp_base), "--quiet"], out / "compensate_base.txt")
    res.files += ["bowl_compensated.nc", "BLOCKS.csv", "compensate.txt",
                  "bowl_compensated_base.nc", "compensate_base.txt"]


def _render_and_check(machine, diag, truth, out: Path, programs: tuple, res: DemoResult) -> None:
    """Step 6: render the error map and cut the bowl (the programs (bowl, compensated with the
    extended model, with the base model)) on the virtual machine; the figures go into ``res.bowl``."""
    from .viz.render import render_error_map
    from .viz.surface import program_error_map, read_program_points
    prog, prog_c, prog_b = (read_program_points(p, machine) for p in programs)
    r = BOWL_TOOL_RADIUS_MM
    smap = program_error_map(machine, diag.model, prog, prog_c, tool_radius_mm=r)
    rr = render_error_map(smap, out / "map.png")
    actual = program_error_map(machine, truth, prog, prog_c, tool_radius_mm=r)
    # what the virtual machine really cut, labelled so: not the model's own residual
    render_error_map(actual, out / "map_cut.png", shows="truth")
    res.files += ["map.png", "map.vtp", "map_cut.png", "map_cut.vtp"]
    actual_base = program_error_map(machine, truth, prog, prog_b, tool_radius_mm=r)
    st = smap.stats()
    res.bowl.update({
        "points": st["n_points"], "renderer": rr.backend,
        "predicted_before": (st["rms_before_um"], st["max_before_um"]),
        "predicted_after": (st["rms_after_um"], st["max_after_um"]),
        "truth_uncompensated": _rms_max(form_error(actual.dn_before_um, actual.points, actual.normals)),
        "truth_base_model": _rms_max(form_error(actual_base.dn_after_um, actual_base.points,
                                                actual_base.normals)),
        "truth_extended_model": _rms_max(form_error(actual.dn_after_um, actual.points, actual.normals))})


def summary_rows(res: DemoResult, report: dict, diag) -> list:
    """The summary table: (what, value) rows."""
    rows = [("hidden effect (truth)", f"backlash of X, {res.hidden['magnitude_um']:.2f} um"),
            ("noise floor found", f"{report['noise_um']:.3f} um"),
            ("base model (the simulation)", f"rms {report['base']['rms_um']:.3f} um, held-out "
                                            f"{report['base']['heldout_rms_um']:.3f} um")]
    for f in report["findings"]:
        params = ", ".join(f"{k} {v:.3g}" if isinstance(v, (int, float)) else f"{k} {v}"
                           for k, v in f["params"].items())
        rows.append((f"found: {f['effect']} {f['axis']}".rstrip(), params))
        if f.get("evidence"):
            rows.append(("  evidence", textwrap.fill(f["evidence"], 70)))
        rows.append(("  held-out rms gain", f"{f['heldout_rms_before_um']:.3f} -> "
                                            f"{f['heldout_rms_after_um']:.3f} um"))
    rows.append(("extended model", f"rms {report['final']['rms_um']:.3f} um, held-out "
                                   f"{report['final']['heldout_rms_um']:.3f} um; verdict "
                                   f"{report['verdict']}"))
    b = res.bowl

    def rm(key):
        return f"rms {b[key][0]:.3f} um, max {b[key][1]:.3f} um"

    rows += [("bowl, predicted by MODEL.json", f"before {rm('predicted_before')}"),
             ("", f"after  {rm('predicted_after')}"),
             ("bowl as cut by the virtual machine", f"uncompensated     {rm('truth_uncompensated')}"),
             ("  (form: true normal error less rigid)", f"base model comp.  {rm('truth_base_model')}"),
             ("", f"extended model    {rm('truth_extended_model')}")]
    before = b["truth_uncompensated"][0]
    rows.append(("form error removed (truth rms)",
                 f"{100 * (1 - b['truth_base_model'][0] / before):.0f} % with the base model, "
                 f"{100 * (1 - b['truth_extended_model'][0] / before):.0f} % with the extended model "
                 "(Qi and Yang 2016: about 30 % on a real cut)"))
    return rows


def format_table(rows) -> str:
    """Two columns; a value with line breaks continues under itself."""
    w = max(len(a) for a, _ in rows)
    return "\n".join(f"{a:<{w}}  " + str(b).replace("\n", "\n" + " " * (w + 2)) for a, b in rows)
