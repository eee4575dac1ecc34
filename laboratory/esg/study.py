"""The ESG readout-strategy study (report 004, Figure 2): its curves, the report's two
points and the edge resolutions, and Figure 2's plot. It needs no measurement, so the run
has the plot child compute and draw it while the rack runs (``study_plot``): the run
itself never imports scipy.optimize (issue 17). ``procedures.esg.strategy`` is imported
where it is used."""

from __future__ import annotations

from pathlib import Path

from laboratory.esg.plots import GOAL_ARCSEC

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
    from procedures.esg import strategy

    curve, points, edge = study()
    strategy.figure2_plot(rows=curve, path=path)
    return curve, points, edge
