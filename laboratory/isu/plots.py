"""Plots of a run, rendered from its record (matplotlib, no display).

matplotlib is imported when a plot is drawn, not with this module: a run draws its plots
after its record is closed, and a command that draws none never pays for it.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from laboratory.plot_worker import png_options
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.count_sigma import speed_count_sigma  # the fit's own weights
from procedures.isu.nonlinearity import fit_nonlinearity

if TYPE_CHECKING:
    from types import ModuleType

TRUTH_SIGMAS = 4.0  # the simulation's truth check: |error| within 4 predicted sigma


def pyplot() -> ModuleType:
    """matplotlib.pyplot on the Agg backend (no display), imported on first use: about
    0.3 s that a command drawing no plot does not spend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def series_dphi_arcsec(w_deg_hr: np.ndarray, p_dot: np.ndarray) -> float:
    """A gyro's scale factor (arcsec/pulse) from its own II-7 series: the slope of w on P'
    through the origin (deg/hr per pulse/s is arcsec/pulse). Enough for the counts' sigma,
    which needs it to a part in a thousand; the bias leaves 1e-4 at the series' rates."""
    return float(np.sum(np.abs(w_deg_hr) * np.abs(p_dot)) / np.sum(p_dot * p_dot))


def nonlinearity_plot(points: dict[int, list[dict]], path: Path,
                      noise: NoiseSpec | None = None) -> None:
    """Chart II-7 step 16: output frequency against total rate for each gyro with 1-sigma
    error bars, and what is left after a straight line with the fitted Q_II (w.G)^2 curve
    (the weighted quadratic of step 17, Q_II = a2/a1 in the legend). The counts' sigma
    takes each gyro's DeltaPhi from its own series: the plot is drawn beside the
    calibration's computations, before Chart II-15 has DeltaPhi."""
    if not points:
        return
    noise = noise or NoiseSpec.model_validate({})
    plt = pyplot()
    fig, axes = plt.subplots(2, len(points), figsize=(4.4 * len(points), 6.8), squeeze=False)
    for i, (k, rows) in enumerate(sorted(points.items())):
        w = np.array([r["w_deg_hr"] for r in rows])
        p = np.array([r["p_dot"] for r in rows])
        gates = np.abs(np.array([r["counts"] for r in rows]) / p)
        dphi = series_dphi_arcsec(w, p)
        sig_counts = np.array([speed_count_sigma(noise, g, abs(pp), dphi)
                               for g, pp in zip(gates, p, strict=True)])
        sig_p = sig_counts / gates  # pulses/s
        fit = fit_nonlinearity(rows, sig_counts)
        ww = np.linspace(w.min(), w.max(), 200)
        quad = fit["a0"] + fit["a1"] * ww + fit["a2"] * ww**2
        ax = axes[0][i]
        ax.errorbar(w / 1e3, p / 1e3, sig_p / 1e3, fmt="o", capsize=2, label="measured")
        ax.plot(ww / 1e3, quad / 1e3, "-", lw=0.8, label="quadratic fit")
        ax.set_title(f"gyro {k}", y=1.0)  # y given: see png_options
        ax.set_xlabel("total rate w (10^3 deg/hr)")
        ax.set_ylabel("output frequency P' (kpulses/s)")
        ax.legend(fontsize=7)
        lin = fit["a0"] + fit["a1"] * w
        ax = axes[1][i]
        ax.errorbar(w / 1e3, p - lin, sig_p, fmt="o", capsize=2,
                    label="measured - straight part (+/- 1 sigma)")
        ax.plot(ww / 1e3, fit["a2"] * ww**2, "-",
                label=f"fit: Q_II = {fit['Q_II']:.3g} +/- {fit['sigma']:.2g} hr/deg")
        ax.set_xlabel("total rate w (10^3 deg/hr)")
        ax.set_ylabel("P' - (a0 + a1 w) (pulses/s)")
        ax.legend(fontsize=7)
    fig.suptitle("Gyro scale-factor nonlinearity (Chart II-7)")
    # fixed margins, not tight_layout: its extra pass over the text took half the drawing
    fig.subplots_adjust(left=0.22 / len(points), right=0.985, bottom=0.075, top=0.9,
                        wspace=0.32, hspace=0.3)
    fig.savefig(path, dpi=110, **png_options())
    plt.close(fig)


def results_plot(rows: list[dict], path: Path) -> bool:
    """One bar per determined constant: error over its predicted sigma with the +/-4 sigma
    truth check (simulation), or else |estimate| over its acceptance limit (the contract's
    ``limit``) with the limit at 1. False (nothing written) when no row has either."""
    sim = [r for r in rows if r.get("error") is not None and r.get("sigma")]
    judged = [r for r in rows if r.get("estimate") is not None and r.get("limit")]
    if sim:
        use, vals = sim, [r["error"] / r["sigma"] for r in sim]
        xlabel, bound = "error / predicted sigma (truth check, simulation only)", TRUTH_SIGMAS
    elif judged:
        use, vals = judged, [abs(r["estimate"]) / abs(r["limit"]) for r in judged]
        xlabel, bound = "|estimate| / acceptance limit", 1.0
    else:
        return False
    labels = [f"{r['instrument']} {r['parameter']} ({r['units']})" for r in use]
    plt = pyplot()
    from matplotlib.collections import PolyCollection
    from matplotlib.transforms import blended_transform_factory

    fig, ax = plt.subplots(figsize=(8, max(2.5, 1.2 + 0.22 * len(use))))
    colours = ["tab:red" if abs(v) > bound else "tab:blue" for v in vals]
    # the bars as one collection and the names as plain texts beside the axis: what barh
    # and set_yticks draw, without an artist per bar and five per tick (issue 17: 0.28 to
    # 0.20 s of the plot child, which draws it while the alignments run)
    ax.add_collection(PolyCollection(
        [[(0.0, i - 0.4), (v, i - 0.4), (v, i + 0.4), (0.0, i + 0.4)]
         for i, v in enumerate(vals)], facecolors=colours, edgecolors="none"))
    for b in (bound, -bound) if sim else (bound,):
        ax.axvline(b, color="k", ls="--", lw=0.8)
    ax.autoscale_view()
    ax.set_yticks([])
    ax.invert_yaxis()
    beside_axis = blended_transform_factory(ax.transAxes, ax.transData)
    for i, label in enumerate(labels):
        ax.text(-0.01, i, label, transform=beside_axis, ha="right", va="center", fontsize=7)
    ax.set_xlabel(xlabel)
    ax.set_title("Calibration Results Sheet (Chart II-5): "
                 + ("error over sigma" if sim else "estimate against limits"), y=1.0)
    # fixed margins from the longest label (7 pt: about 0.058 in a character), not
    # tight_layout, whose extra pass over the text took half the drawing
    height = fig.get_figheight()
    fig.subplots_adjust(left=min(0.6, (0.15 + 0.058 * max(map(len, labels))) / 8.0),
                        right=0.97, bottom=0.55 / height, top=1.0 - 0.4 / height)
    fig.savefig(path, dpi=110, **png_options())
    plt.close(fig)
    return True
