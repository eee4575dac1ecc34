"""The gyrocompassing test's plot, in a module of its own: the plot child
(laboratory.plot_worker) imports it with matplotlib while the test runs, and nothing of the
laboratory (issue 17: a light child leaves the run its CPU)."""

from __future__ import annotations

from pathlib import Path

from laboratory.plot_worker import png_options

PHASES = ("operating", "shutdown")  # laboratory.cigtf.gyrocompassing's


def theta_plot(res: dict, path: Path) -> None:
    """theta of every run with its standard error, one panel per phase, runs numbered as
    the run table numbers them (operating 1-25, shutdown 1-10); phase means dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    phases = [ph for ph in PHASES if any(r["phase"] == ph for r in res["runs"])] or [PHASES[0]]
    sizes = [max(1, sum(r["phase"] == ph for r in res["runs"])) for ph in phases]
    fig, axes = plt.subplots(1, len(phases), figsize=(9, 4), sharey=True, squeeze=False,
                             gridspec_kw={"width_ratios": sizes})
    truth = res["truth"]["theta_arcsec"]
    for ax, ph, colour in zip(axes[0], phases, ("tab:blue", "tab:orange"), strict=False):
        rows = [r for r in res["runs"] if r["phase"] == ph]
        x = [r["run"] for r in rows]
        ax.errorbar(x, [r["theta_arcsec"] for r in rows], [r["sigma_arcsec"] for r in rows],
                    fmt="o", color=colour, capsize=2, label=f"{ph} runs (+/- 1 sigma)")
        p = next((q for q in res["phases"] if q["phase"] == ph), None)
        if p is not None and x:
            ax.hlines(p["theta_arcsec"], min(x) - 0.5, max(x) + 0.5, colors=colour,
                      linestyles="--", label=f"{ph} mean {p['theta_arcsec']:+.2f} arcsec")
        if truth is not None:
            ax.axhline(truth, color="k", lw=0.8, label=f"truth (eq. 26) {truth:+.2f} arcsec")
        ax.set_xlabel("run")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_title(f"{ph} phase (runs as the run table numbers them)" if ph == PHASES[0]
                     else f"{ph} phase", fontsize=10, y=1.0)
        ax.legend(fontsize=7, loc="best")
    axes[0][0].set_ylabel("gyrocompassing error theta (arcsec)")
    fig.suptitle("CIGTF gyrocompassing accuracy test")
    # fixed margins, not tight_layout: its extra pass over the text took half the drawing
    fig.subplots_adjust(left=0.075, right=0.985, bottom=0.12, top=0.86, wspace=0.04)
    fig.savefig(path, dpi=110, **png_options())
    plt.close(fig)
