"""Residual plots for diagnose: residual versus position, before and after a model extension.

matplotlib (imported here, when drawing), off-screen (Agg). Two panels side by side on one y scale:
the residuals of the base model and those of the extended model against the position of the moving
axis, coloured by group (file, approach direction ...), with RMS and largest magnitude in each title.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_write

#: colours of up to ten groups (matplotlib's tab10), then repeated
_MARKERS = "o^sDv<>ph*"


def residual_stats(residual: np.ndarray) -> dict:
    """{'rms': ..., 'max': ...} of the finite values (NaN when there are none)."""
    r = np.asarray(residual, dtype=float)
    r = r[np.isfinite(r)]
    if not r.size:
        return {"rms": float("nan"), "max": float("nan")}
    return {"rms": float(np.sqrt(np.mean(r ** 2))), "max": float(np.max(np.abs(r)))}


def render_residuals(position, before, after, out_png, *, groups=None, xlabel: str = "position (mm)",
                     unit: str = "um", title: str | None = None,
                     labels: tuple[str, str] = ("base model", "extended model"),
                     size: tuple[int, int] = (1200, 500)) -> dict:
    """Draw residual versus position before and after an extension; write ``out_png`` atomically.

    position : (n,) position of each observation (e.g. the moving axis, mm; or an angle, deg).
    before, after : (n,) residuals (observed minus predicted) in ``unit`` of the base and the
        extended model, for the same observations (NaN: not drawn).
    groups : (n,) labels (file tag, approach direction ...) drawn with their own colour and marker and
        listed in a legend, or None.
    Returns {'before': {'rms', 'max'}, 'after': {'rms', 'max'}} in ``unit``.
    """
    x = np.asarray(position, dtype=float).reshape(-1)
    rb = np.asarray(before, dtype=float).reshape(-1)
    ra = np.asarray(after, dtype=float).reshape(-1)
    if not (x.shape == rb.shape == ra.shape):
        raise ValueError(f"position, before and after must have one value per observation, got "
                         f"{x.shape}, {rb.shape}, {ra.shape}")
    g = np.full(x.shape, "", dtype=object) if groups is None else np.asarray(groups, dtype=object)
    if g.shape != x.shape:
        raise ValueError("groups must have one label per observation")
    out_png = Path(out_png)
    if out_png.suffix.lower() != ".png":
        raise InputError("the residual plot must be a .png file", out_png)
    if not out_png.resolve().parent.is_dir():
        raise InputError(f"output folder {out_png.resolve().parent} does not exist", out_png)
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    stats = {"before": residual_stats(rb), "after": residual_stats(ra)}
    lim = max([v["max"] for v in stats.values() if np.isfinite(v["max"])] + [1e-9]) * 1.08
    dpi = 100
    fig, axes = plt.subplots(1, 2, figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi, sharey=True,
                             constrained_layout=True)
    names = list(dict.fromkeys(g.tolist()))
    cmap = plt.get_cmap("tab10")
    try:
        for ax, r, label, key in zip(axes, (rb, ra), labels, ("before", "after")):
            for k, name in enumerate(names):
                sel = (g == name) & np.isfinite(r) & np.isfinite(x)
                ax.scatter(x[sel], r[sel], s=9, color=cmap(k % 10), marker=_MARKERS[(k // 10) % 10],
                           label=str(name) if name != "" else None, linewidths=0)
            ax.axhline(0.0, color="black", linewidth=0.8)
            st = stats[key]
            ax.set_title(f"{label}\nRMS {st['rms']:.3g} {unit}, max {st['max']:.3g} {unit}")
            ax.set_xlabel(xlabel)
            ax.set_ylim(-lim, lim)
            ax.grid(True, linewidth=0.3)
        axes[0].set_ylabel(f"residual ({unit})")
        if any(n != "" for n in names):
            axes[1].legend(loc="upper right", fontsize=8, markerscale=1.5)
        if title:
            fig.suptitle(title)
        with atomic_write(out_png, "wb") as f:
            fig.savefig(f, dpi=dpi, format="png")
    finally:
        plt.close(fig)
    return stats
