"""The ESG calibration's schedule plot, in a module of its own: the plot child
(laboratory.plot_worker) imports it with matplotlib while the run runs, and nothing of the
laboratory (issue 17: a light child leaves the run its CPU). A schedule is plain data:
name, and the calibration and readout rows of its ``ScheduleResult``."""

from __future__ import annotations

from pathlib import Path

from laboratory.plot_worker import png_options

GOAL_ARCSEC = 15.0  # laboratory.esg.calibration's: the readout goal (arcsec)


def schedule_plot(schedules: list[dict], path: Path) -> None:
    """Compensated minus assigned (or true) colatitude per schedule, with the report's
    +/-15 arcsec goal lines labelled and the legend outside the data (right margin)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(schedules), 1, figsize=(10, 3.2 * len(schedules)),
                             sharex=True, squeeze=False)
    for ax, res in zip(axes[:, 0], schedules, strict=True):
        for rows, mark, what in ((res["calibration"], "o", "fit"),
                                 (res["readout"], "s", "readout")):
            x = [r["colatitude_deg"] for r in rows]
            ax.plot(x, [r["error_arcsec"] for r in rows], mark, ms=4, mfc="none",
                    label=f"{what}: measured")
            if all(r["true_error_arcsec"] is not None for r in rows):
                ax.plot(x, [r["true_error_arcsec"] for r in rows], mark, ms=3,
                        label=f"{what}: true")
        ax.axhline(GOAL_ARCSEC, color="k", lw=0.6, ls="--",
                   label=f"goal +/-{GOAL_ARCSEC:g} arcsec")
        ax.axhline(-GOAL_ARCSEC, color="k", lw=0.6, ls="--")
        for y in (GOAL_ARCSEC, -GOAL_ARCSEC):
            ax.annotate(f"{y:+g} arcsec goal", (1.0, y), xycoords=("axes fraction", "data"),
                        xytext=(-4, 2 if y > 0 else -9), textcoords="offset points",
                        ha="right", fontsize=7)
        ax.set_ylabel("error (arcsec)")
        ax.set_title(f"schedule {res['name']}: compensated minus assigned / true colatitude",
                     y=1.0)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    axes[-1, 0].set_xlabel("colatitude of pickoff 2 (deg)")
    # fixed margins (in inches, the figure grows with the schedules), not tight_layout: its
    # extra pass over the text took a third of the drawing; the right margin holds the legend
    height = 3.2 * len(schedules)
    fig.subplots_adjust(left=0.075, right=0.85, bottom=0.6 / height, top=1.0 - 0.37 / height,
                        hspace=0.17)
    fig.savefig(path, dpi=110, **png_options())
    plt.close(fig)
