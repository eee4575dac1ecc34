"""The ESG readout-strategy study (report 004, Figure 2): its curves, the report's two
points and the edge resolutions, and Figure 2's plot. It needs no measurement, so the run
has the plot child compute and draw it while the rack runs (``study_plot``): the run
itself never imports scipy.optimize (issue 17). ``procedures.esg.strategy`` is imported
where it is used."""

from __future__ import annotations

from pathlib import Path

from laboratory.esg.plots import GOAL_ARCSEC
from laboratory.plot_worker import png_options

STUDY_RANGES = tuple(range(35, 48))
STUDY_POINTS = 6000
REPORT_POINTS = (("great_circle", 43.0), ("cosine", 37.0))


def study() -> tuple[list[dict], list[dict], dict]:
    """Figure 2 curves, the report's two points (both conventions) and edge resolutions."""
    from procedures.esg import strategy

    curve = strategy.figure2_table(STUDY_RANGES, points=STUDY_POINTS)
    points: list[dict] = []
    chart: list[dict] = []
    mixed: dict[str, float] = {}  # the mixed strategy's factor by pattern
    for pattern, rng in REPORT_POINTS:
        for strat in ("two_pickoff", "mixed"):
            f = strategy.amplification(pattern, strat, rng)
            if strat == "mixed":
                mixed[pattern] = f
            points.append({"pattern": pattern, "range_deg": rng, "strategy": strat,
                           "factor": f})
            fc = strategy.amplification(pattern, strat, rng, convention="chart")
            chart.append({"pattern": pattern, "range_deg": rng, "strategy": strat,
                          "factor": fc})
    edge = {"great_circle_43_microinch":
            strategy.edge_resolution_microinch(GOAL_ARCSEC, mixed["great_circle"]),
            "cosine_37_microinch": strategy.edge_resolution_microinch(GOAL_ARCSEC,
                                                                      mixed["cosine"]),
            "report_factors": {"great_circle_43": 1.55, "cosine_37": 1.20},
            "chart_convention": chart,
            "cosine_mixed_minimum_deg": strategy.cosine_mixed_minimum()}
    return curve, points, edge


def study_plot(path: Path) -> tuple[list[dict], list[dict], dict]:
    """The study, with Figure 2 drawn to ``path``: what the run records of it."""
    curve, points, edge = study()
    figure2_plot(rows=curve, path=path)
    return curve, points, edge


def figure2_plot(rows: list[dict], path: Path, report_points: bool = True) -> None:
    """Figure 2 as a PNG: factor against the pattern's top-edge colatitude."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    styles = {("great_circle", "two_pickoff"): ("tab:red", "--"),
              ("great_circle", "mixed"): ("tab:red", "-"),
              ("cosine", "two_pickoff"): ("tab:blue", "--"),
              ("cosine", "mixed"): ("tab:blue", "-")}
    for (pattern, strategy), (colour, ls) in styles.items():
        sel = sorted((r for r in rows if r["pattern"] == pattern and r["strategy"] == strategy),
                     key=lambda r: r["range_deg"])
        if sel:
            ax.plot([r["range_deg"] for r in sel], [r["factor"] for r in sel], color=colour,
                    ls=ls, marker=".", label=f"{pattern.replace('_', ' ')}, {strategy}")
    if report_points:
        ax.plot([43.0], [1.55], "k^", label="report: great circle 43 deg, 1.55")
        ax.plot([37.0], [1.20], "kv", label="report: cosine mixed 37 deg, 1.20")
    ax.axvline(45.0, color="0.6", lw=0.8)
    ax.invert_xaxis()
    ax.set_xlabel("pattern top-edge colatitude theta0 (deg); range grows to the right")
    ax.set_ylabel("RMS amplification of line-edge error")
    conv = {r.get("convention", "sphere") for r in rows}
    ax.set_title("ESG readout strategy (report 004, Figure 2); " + ", ".join(sorted(conv)),
                 y=1.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    # fixed margins, not tight_layout: its extra pass over the text took a third of the drawing
    fig.subplots_adjust(left=0.095, right=0.98, bottom=0.13, top=0.92)
    fig.savefig(path, dpi=110, **png_options())
    plt.close(fig)
