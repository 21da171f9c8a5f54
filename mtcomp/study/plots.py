"""A study's summary at a glance: three PNG plots and one HTML page that holds them and the table.

* ``remaining_vs_bounds.png``: per program (and model, method, temperature where the study has
  several), the remaining rms error (over the corrected blocks, under the judging model) for each
  bound setting, draw 0, the error before correction drawn dashed;
* ``draws_spread.png``: per bound setting, what the draws of the model from its covariance change:
  each draw's remaining rms error less draw 0's of the same program and settings (box: quartiles,
  whiskers: range);
* ``pareto.png``: the correction effort (rms length of the linear corrections) against the
  remaining rms error, one point per bound setting (and method, temperature), medians over programs
  and draws; the settings no other beats in both joined (the Pareto front).

matplotlib with the Agg backend (no screen needed).
"""
from __future__ import annotations

import base64
import html
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_write


#: the plots' file names, in the order :func:`plot_summary` returns them
PLOTS = ("remaining_vs_bounds.png", "draws_spread.png", "pareto.png")


def _ok(rows):
    return [r for r in rows if r["status"] == "ok" and r["rms_after_um"] is not None]


def pareto_front(effort, error) -> np.ndarray:
    """Indices of the points no other point beats in both (lower effort and lower error, one of
    them strictly), sorted by effort."""
    effort, error = np.asarray(effort, float), np.asarray(error, float)
    order = np.lexsort((error, effort))
    front, best = [], np.inf
    for i in order:
        if error[i] < best:
            front.append(i)
            best = error[i]
    return np.array(front, dtype=int)


def _save(fig, path: Path) -> Path:
    with atomic_write(path, "wb") as f:
        fig.savefig(f, format="png", dpi=110)
    return path


def _case(r) -> tuple:
    """What a row compensated, draws aside: (program, model, method, temperature)."""
    return (r["program"], r["model"], r["method"], r["temperature"])


def _case_label(case, cases) -> str:
    """The parts of ``case`` that differ between ``cases``, joined (the program at least, by its
    file name where the names tell the programs apart: a legend of absolute paths is unreadable)."""
    names = {Path(str(c[0])).name for c in cases}
    programs = {str(c[0]) for c in cases}
    program = Path(str(case[0])).name if len(names) == len(programs) else str(case[0])
    parts = [program] + [v for k, v in enumerate(case[1:], 1) if len({c[k] for c in cases}) > 1]
    return ", ".join(parts)


def plot_summary(rows: list[dict], out) -> list[Path]:
    """Write the three plots under ``out``; returns their paths (none without a finished task, and
    the plots of an earlier run are removed then, so that none describes another study)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out = Path(out)
    ok = _ok(rows)
    if not ok:
        for name in PLOTS:
            (out / name).unlink(missing_ok=True)
        return []
    bounds = list(dict.fromkeys(r["bounds"] for r in rows))
    cases = list(dict.fromkeys(_case(r) for r in ok))
    colours = plt.cm.tab10(np.linspace(0, 1, 10))
    x = np.arange(len(bounds))
    paths = []

    fig, ax = plt.subplots(figsize=(8, 4.8), constrained_layout=True)
    for k, case in enumerate(cases):
        mine = [r for r in ok if _case(r) == case and r["draw"] == 0]
        if not mine:
            continue
        c = colours[k % 10]
        after = [next((r["rms_after_um"] for r in mine if r["bounds"] == b), np.nan) for b in bounds]
        ax.plot(x, after, "o-", color=c, label=_case_label(case, cases))
        ax.axhline(np.median([r["rms_before_um"] for r in mine]), color=c, ls="--", lw=0.8)
    ax.set_xticks(x, bounds, rotation=20, ha="right")
    ax.set_xlabel("bound setting")
    ax.set_ylabel("remaining rms error, um (dashed: before)")
    ax.set_title("Remaining error against each bound setting (corrected blocks, draw 0)")
    ax.grid(alpha=0.3)
    if len(cases) <= 12:
        ax.legend(fontsize=7, loc="best")
    paths.append(_save(fig, out / PLOTS[0]))
    plt.close(fig)

    # the draws' own effect: each draw's remaining error less draw 0's of the same case and setting
    fig, ax = plt.subplots(figsize=(8, 4.8), constrained_layout=True)
    base = {(_case(r), r["bounds"]): r["rms_after_um"] for r in ok if r["draw"] == 0}
    data = [[r["rms_after_um"] - base[(_case(r), b)] for r in ok
             if r["bounds"] == b and r["draw"] > 0 and (_case(r), b) in base] for b in bounds]
    n_draws = max(r["draw"] for r in rows)
    ax.boxplot([d if d else [np.nan] for d in data], whis=(0, 100))
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xticks(np.arange(1, len(bounds) + 1), bounds, rotation=20, ha="right")
    ax.set_xlabel("bound setting")
    ax.set_ylabel("remaining rms error, um, less draw 0's")
    ax.set_title(f"What {n_draws} draws of the model from its covariance change "
                 f"(over {len(cases)} program{'s' if len(cases) != 1 else ''} and settings)"
                 if n_draws else "No draws asked (draws = 0)")
    ax.grid(alpha=0.3, axis="y")
    paths.append(_save(fig, out / PLOTS[1]))
    plt.close(fig)

    # one point per bound setting (and method, temperature): medians over programs and draws, so
    # that the front compares settings, not programs of different sizes
    fig, ax = plt.subplots(figsize=(8, 4.8), constrained_layout=True)
    groups = {}
    for r in ok:
        groups.setdefault((r["bounds"], r["method"], r["temperature"]), []).append(r)
    keys = list(groups)
    effort = np.array([np.median([r["correction_rms_um"] for r in groups[k]]) for k in keys])
    error = np.array([np.median([r["rms_after_um"] for r in groups[k]]) for k in keys])
    for i, k in enumerate(keys):
        label = ", ".join([k[0]] + [v for j, v in enumerate(k[1:], 1) if len({q[j] for q in keys}) > 1])
        ax.scatter(effort[i], error[i], s=30, color=colours[bounds.index(k[0]) % 10])
        ax.annotate(label, (effort[i], error[i]), fontsize=7, xytext=(4, 4),
                    textcoords="offset points")
    front = pareto_front(effort, error)
    ax.plot(effort[front], error[front], "k-", lw=0.8, label="Pareto front")
    ax.set_xlabel("correction effort: rms correction, um (median over programs and draws)")
    ax.set_ylabel("remaining rms error, um (median)")
    ax.set_title("Correction effort against remaining error, per bound setting")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    paths.append(_save(fig, out / PLOTS[2]))
    plt.close(fig)
    return paths


def write_html(rows: list[dict], plots: list[Path], out, title: str) -> Path:
    """index.html under ``out``: the plots (embedded) and, per program and bound setting, the
    median remaining error over the draws, with the failed tasks listed."""
    out = Path(out)
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
             "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
             "td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}"
             "td:first-child,th:first-child{text-align:left}</style></head><body>",
             f"<h1>{html.escape(title)}</h1>",
             f"<p>{len(rows)} tasks, {sum(r['status'] == 'ok' for r in rows)} finished, "
             f"{sum(r['status'] != 'ok' for r in rows)} failed. The whole table: "
             "<a href='results.csv'>results.csv</a>, <a href='results.parquet'>results.parquet</a>."
             "</p>"]
    for p in plots:
        data = base64.b64encode(Path(p).read_bytes()).decode()
        parts.append(f"<p><img alt='{p.stem}' src='data:image/png;base64,{data}'></p>")
    ok = _ok(rows)
    if ok:
        parts.append("<h2>Remaining rms error (um), median over draws</h2><table><tr><th>program"
                     "</th><th>model</th><th>method</th><th>temperature</th><th>bounds</th>"
                     "<th>before</th><th>after</th><th>after, worst draw</th>"
                     "<th>corrected blocks</th></tr>")
        keys = list(dict.fromkeys(_case(r) + (r["bounds"],) for r in ok))
        for key in keys:
            mine = [r for r in ok if _case(r) + (r["bounds"],) == key]
            after = [r["rms_after_um"] for r in mine]
            cells = "".join(f"<td>{html.escape(str(v))}</td>" for v in key)
            parts.append(f"<tr>{cells}<td>{np.median([r['rms_before_um'] for r in mine]):.3f}</td>"
                         f"<td>{np.median(after):.3f}</td><td>{max(after):.3f}</td>"
                         f"<td>{mine[0]['corrected_blocks']}</td></tr>")
        parts.append("</table>")
    bad = [r for r in rows if r["status"] != "ok"]
    if bad:
        parts.append(f"<h2>Failed tasks ({len(bad)})</h2><ul>")
        for r in bad[:200]:
            what = ", ".join(html.escape(str(v)) for v in _case(r) + (r["bounds"], f"draw {r['draw']}"))
            parts.append(f"<li>{what}: {html.escape(r['error'] or '')}</li>")
        if len(bad) > 200:
            parts.append(f"<li>... and {len(bad) - 200} more (results.csv lists them all)</li>")
        parts.append("</ul>")
    parts.append("</body></html>\n")
    path = out / "index.html"
    with atomic_write(path, "w") as f:
        f.write("\n".join(parts))
    return path
