"""ISO 230-3 style drift plot of a thermal fit: each channel's drift over time, measured, fitted and
predicted forward in time, with the spindle speed on top. matplotlib (Agg, off-screen), imported
when drawing."""
from __future__ import annotations

import numpy as np


def plot_drift(fit, out, width_px: int = 1100, row_px: int = 190) -> None:
    """Draw :class:`~mtcomp.thermal.ThermalFit` ``fit`` as PNG into ``out`` (path or binary file).

    One panel per channel: the drift (reading minus the first reading, um) measured, the chosen
    model fitted to every reading, and each block of the record predicted from the blocks before it
    (forward-chained validation); the title gives the largest drift and the forward rms. A top panel
    shows the spindle speed (rpm) when the file has one.
    """
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    t_h = (fit.t_s - fit.t_s[0]) / 3600.0
    spindle = np.isfinite(fit.spindle_rpm).any() and np.nanmax(np.abs(fit.spindle_rpm)) > 0
    rows = len(fit.channels) + int(spindle)
    dpi = 100
    fig, axes = plt.subplots(rows, 1, figsize=(width_px / dpi, row_px * rows / dpi), dpi=dpi,
                             sharex=True, constrained_layout=True, squeeze=False)
    axes = axes[:, 0]
    try:
        if spindle:
            axes[0].plot(t_h, fit.spindle_rpm, color="black", linewidth=0.8)
            axes[0].set_ylabel("spindle (rpm)")
            taus = ", ".join(f"{x:g}" for x in fit.chosen.time_constants_s)
            axes[0].set_title(f"drift model: {fit.chosen.label}"
                              + (f" (time constants {taus} s)" if taus else ""))
        y0 = fit.measured_um[0]
        for j, ch in enumerate(fit.channels):
            ax = axes[j + int(spindle)]
            ax.plot(t_h, fit.measured_um[:, j] - y0[j], color="black", linewidth=0.8, label="measured")
            ax.plot(t_h, fit.fitted_um[:, j] - y0[j], color="tab:blue", linewidth=0.8, label="fitted")
            ax.plot(t_h, fit.forward_um[:, j] - y0[j], color="tab:red", linewidth=0.8,
                    label="predicted from the past")
            ax.set_ylabel(f"{ch} (um)")
            ax.set_title(f"{ch}: max drift {fit.max_drift_um[j]:.3g} um, forward rms "
                         f"{fit.chosen.forward_rms_um[j]:.3g} um", fontsize=9)
            ax.grid(True, linewidth=0.3)
        axes[int(spindle)].legend(loc="best", fontsize=8)
        axes[-1].set_xlabel("time (h)")
        fig.savefig(out, format="png")
    finally:
        plt.close(fig)
