"""A study's summary at a glance: three PNG plots and one HTML page that holds them and the table.

* ``remaining_vs_bounds.png``: per program, the remaining rms error (over the corrected blocks,
  under the judging model) for each bound setting, the error before correction drawn dashed;
* ``draws_spread.png``: per bound setting, the spread of the remaining rms error over the draws of
  the model from its covariance (box: quartiles, whiskers: range; with no draws, one point each);
* ``pareto.png``: the correction effort (rms length of the linear corrections) against the
  remaining rms error, one point per program, method, temperature and bound setting (medians over
  the draws), coloured by bound setting; the points no other beats in both joined.

matplotlib with the Agg backend (no screen needed).
"""
from __future__ import annotations

import base64
import html
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_write


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


def plot_summary(rows: list[dict], out) -> list[Path]:
    """Write the three plots under ``out``; returns their paths (none without a finished task)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out = Path(out)
    ok = _ok(rows)
    if not ok:
        return []
    bounds = list(dict.fromkeys(r["bounds"] for r in rows))
    programs = list(dict.fromkeys(r["program"] for r in rows))
    paths = []

    fig, ax = plt.subplots(figsize=(8, 4.8), constrained_layout=True)
    x = np.arange(len(bounds))
    colours = plt.cm.tab10(np.linspace(0, 1, 10))
    for k, prog in enumerate(programs):
        mine = [r for r in ok if r["program"] == prog and r["draw"] == 0]
        if not mine:
            continue
        c = colours[k % 10]
        after = [np.mean([r["rms_after_um"] for r in mine if r["bounds"] == b] or [np.nan])
                 for b in bounds]
        before = np.mean([r["rms_before_um"] for r in mine])
        ax.plot(x, after, "o-", color=c, label=prog)
        ax.axhline(before, color=c, ls="--", lw=0.8)
    ax.set_xticks(x, bounds, rotation=20, ha="right")
    ax.set_xlabel("bound setting")
    ax.set_ylabel("remaining rms error, um (dashed: before)")
    ax.set_title("Remaining error against each bound setting (corrected blocks, draw 0)")
    ax.grid(alpha=0.3)
    if len(programs) <= 12:
        ax.legend(fontsize=7, loc="best")
    paths.append(_save(fig, out / "remaining_vs_bounds.png"))
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(8, 4.8), constrained_layout=True)
    data = [[r["rms_after_um"] for r in ok if r["bounds"] == b] for b in bounds]
    ax.boxplot([d if d else [np.nan] for d in data], whis=(0, 100))
    ax.set_xticks(np.arange(1, len(bounds) + 1), bounds, rotation=20, ha="right")
    n_draws = max(r["draw"] for r in rows)
    ax.set_xlabel("bound setting")
    ax.set_ylabel("remaining rms error, um")
    ax.set_title(f"Spread over {n_draws} draws of the model from its covariance, all programs"
                 if n_draws else "Remaining error over all programs (no draws asked)")
    ax.grid(alpha=0.3, axis="y")
    paths.append(_save(fig, out / "draws_spread.png"))
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(8, 4.8), constrained_layout=True)
    # one point per program, method, temperature and bound setting: the medians over the draws
    groups = {}
    for r in ok:
        groups.setdefault((r["program"], r["method"], r["temperature"], r["bounds"]), []).append(r)
    effort = np.array([np.median([r["correction_rms_um"] for r in g]) for g in groups.values()])
    error = np.array([np.median([r["rms_after_um"] for r in g]) for g in groups.values()])
    which = np.array([bounds.index(k[3]) for k in groups])
    for j, b in enumerate(bounds):
        sel = which == j
        ax.scatter(effort[sel], error[sel], s=18, alpha=0.7, color=colours[j % 10], label=b)
    front = pareto_front(effort, error)
    ax.plot(effort[front], error[front], "k-", lw=0.8, label="Pareto front")
    ax.set_xlabel("correction effort: rms correction, um")
    ax.set_ylabel("remaining rms error, um")
    ax.set_title("Correction effort against remaining error (medians over draws)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, title="bound setting", title_fontsize=7)
    paths.append(_save(fig, out / "pareto.png"))
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
                     "</th><th>bounds</th><th>before</th><th>after</th><th>after, worst draw</th>"
                     "<th>corrected blocks</th></tr>")
        keys = list(dict.fromkeys((r["program"], r["bounds"]) for r in ok))
        for prog, b in keys:
            mine = [r for r in ok if r["program"] == prog and r["bounds"] == b]
            after = [r["rms_after_um"] for r in mine]
            parts.append(f"<tr><td>{html.escape(prog)}</td><td>{html.escape(b)}</td>"
                         f"<td>{np.median([r['rms_before_um'] for r in mine]):.3f}</td>"
                         f"<td>{np.median(after):.3f}</td><td>{max(after):.3f}</td>"
                         f"<td>{mine[0]['corrected_blocks']}</td></tr>")
        parts.append("</table>")
    bad = [r for r in rows if r["status"] != "ok"]
    if bad:
        parts.append("<h2>Failed tasks</h2><ul>")
        for r in bad[:200]:
            parts.append(f"<li>{html.escape(r['program'])}, {html.escape(r['bounds'])}, draw "
                         f"{r['draw']}: {html.escape(r['error'] or '')}</li>")
        parts.append("</ul>")
    parts.append("</body></html>\n")
    path = out / "index.html"
    with atomic_write(path, "w") as f:
        f.write("\n".join(parts))
    return path
