"""Plots of a run, rendered from its record (matplotlib, no display)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def nonlinearity_plot(points: dict[int, list[dict]], path: Path) -> None:
    """Chart II-7 step 16: output frequency against total rate for each gyro, and what is
    left after a straight line (the Q_II (w.G)^2 curvature the fit measures)."""
    if not points:
        return
    fig, axes = plt.subplots(2, len(points), figsize=(4.2 * len(points), 6.5), squeeze=False)
    for i, (k, rows) in enumerate(sorted(points.items())):
        w = np.array([r["w_deg_hr"] for r in rows])
        p = np.array([r["p_dot"] for r in rows])
        ax = axes[0][i]
        ax.plot(w / 1e3, p / 1e3, "o")
        ax.set_title(f"gyro {k}")
        ax.set_xlabel("total rate w (10^3 deg/hr)")
        ax.set_ylabel("output frequency P' (kpulses/s)")
        lin = np.polyfit(w, p, 1)
        quad = np.polyfit(w, p, 2)
        ww = np.linspace(w.min(), w.max(), 200)
        ax = axes[1][i]
        ax.plot(w / 1e3, p - np.polyval(lin, w), "o", label="data - straight line")
        ax.plot(ww / 1e3, np.polyval(quad, ww) - np.polyval(lin, ww), "-",
                label="quadratic fit - straight line")
        ax.set_xlabel("total rate w (10^3 deg/hr)")
        ax.set_ylabel("residual (pulses/s)")
        ax.legend(fontsize=7)
    fig.suptitle("Gyro scale-factor nonlinearity (Chart II-7)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
