"""`station plan`: the accuracy charts II-18..II-24 for this station, and the times the
configured requirements imply (II-6.2).

Each curve is the covariance model's prediction (procedures.isu.accuracy) over a nominal day
with one gate's time varied and the others at the manual's defaults; a chart that the report
draws with and without bubble-level corrections (the horizontal accelerometer: II-21/II-23,
II-22/II-24) has both. Without level corrections the accelerometer sees the pier's tilt since
the survey's level reading instead of since its own (the table's orientation errors are
modelled as with levels). Written: chart_II-*.png, accuracy.csv, times.json.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rich.console import Console

from laboratory.isu.spec import mounting, noise_spec, site_of
from laboratory.plot_worker import png_options
from laboratory.tables import Column, print_fitted
from procedures.isu.accuracy import GATE_UNITS, Predictor, Times, Unreachable
from procedures.isu.plan import DayPlan
from procedures.isu.settings import collection_times, manual_times, planning_lab
from station.config.isu import StationConfig
from station.config.plan import REQUIREMENT_TEXT
from station.files import atomic_path


@dataclass(frozen=True)
class Curve:
    quantity: str  # a key of Predictor.quantities
    gate: str
    level: bool
    units: str


CHARTS: dict[str, tuple[str, list[Curve]]] = {
    "II-18": ("Gyro scale factor error vs time",
              [Curve("gyro_scale_factor", "gyro 1-6", True, "relative")]),
    "II-19": ("Gyro bias error vs time",
              [Curve("gyro R", "gyro 7-15", True, "deg/hr"),
               Curve("gyro B g", "gyro 7-15", True, "deg/hr"),
               Curve("gyro C g^2", "gyro 7-15", True, "deg/hr")]),
    "II-21": ("Accelerometer scale factor error vs time",
              [Curve("accel_scale_factor_ppm", "accel vertical", True, "ppm"),
               Curve("accel misalignment ppm", "accel horizontal", False, "ppm")]),
    "II-22": ("Accelerometer bias error vs time",
              [Curve("accel_bias_micro_g", "accel horizontal", False, "micro-g")]),
    "II-23": ("Accelerometer scale factor error vs time, with level corrections",
              [Curve("accel misalignment ppm", "accel horizontal", True, "ppm")]),
    "II-24": ("Accelerometer bias error vs time, with level corrections",
              [Curve("accel_bias_micro_g", "accel horizontal", True, "micro-g")]),
}
SECONDS = (60.0, 120.0, 300.0, 600.0, 900.0, 1200.0, 1800.0, 2400.0, 3000.0, 3600.0)
TURNS = (1, 2, 3, 5, 7, 10, 15, 20, 30, 50, 70, 100)


def grid(gate: str, default: Times, plan: DayPlan) -> list[float]:
    """Collection times of a curve: up to the plan's maximum gate, the default among them."""
    longest = 60.0 * plan.requirements.max_gate_minutes
    if gate == "gyro 1-6":
        turn = 360.0 / plan.table_rate_deg_s
        pts = {float(t) for t in TURNS if t * turn <= longest}
    else:
        pts = {t for t in SECONDS if t <= longest}
    return sorted(pts | {default.get(gate)})


def accuracy_table(cfg: StationConfig, plan: DayPlan) -> list[dict]:
    """Every chart's curves as rows: chart, quantity, gate, level, time, units, sigma."""
    plan = plan.model_copy(update={"requirements": cfg.plan})
    lab = planning_lab(plan, site_of(cfg), noise_spec(cfg), f0=cfg.isu.accels[0].f0_hz,
                       t_bi=mounting(cfg))
    default = manual_times(plan)
    pred = Predictor(lab, default)
    cache: dict[tuple[Times, bool], dict[str, float]] = {}
    rows = []
    for chart, (_, curves) in CHARTS.items():
        for c in curves:
            for t in grid(c.gate, default, plan):
                times = default.set(c.gate, t)
                if (times, c.level) not in cache:
                    cache[(times, c.level)] = pred.quantities(pred.covariance(times, c.level))
                rows.append({"chart": chart, "quantity": c.quantity, "gate": c.gate,
                             "level_corrected": c.level, "time": t,
                             "time_units": GATE_UNITS[c.gate], "units": c.units,
                             "sigma": cache[(times, c.level)][c.quantity]})
    return rows


def implied_times(cfg: StationConfig, plan: DayPlan) -> dict:
    """The collection times the config's requirements imply, or the refusal."""
    plan = plan.model_copy(update={"requirements": cfg.plan})
    try:
        times, gates = collection_times(plan, site_of(cfg), noise_spec(cfg),
                                        f0=cfg.isu.accels[0].f0_hz, t_bi=mounting(cfg))
    except Unreachable as e:
        return {"refused": str(e)}
    return {"times": {"turns": times.turns, "gyro_s": times.gyro_s,
                      "accel_vertical_s": times.accel_vertical_s,
                      "accel_horizontal_s": times.accel_horizontal_s},
            "gates": {g: s.model_dump() for g, s in gates.items()}}


def chart_png(chart: str, rows: list[dict], path: Path, required: dict[str, float]) -> None:
    """One chart: sigma against collection time, log-log, a requirement as a dashed line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    title, curves = CHARTS[chart]
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for c in curves:
        pts = [r for r in rows if r["chart"] == chart and r["quantity"] == c.quantity
               and r["level_corrected"] == c.level]
        x = np.array([r["time"] for r in pts])
        if c.gate != "gyro 1-6":
            x = x / 60.0
        label = f"{c.quantity} ({c.gate}{'' if c.level else ', no level corrections'})"
        ax.loglog(x, [r["sigma"] for r in pts], "o-", label=label)
        if c.quantity in required:
            ax.axhline(required[c.quantity], ls="--", color="grey",
                       label=f"required {c.quantity}")
    ax.set_xlabel("whole turns" if curves[0].gate == "gyro 1-6" else "collection time, min")
    ax.set_ylabel(f"1 sigma, {curves[0].units}")
    ax.set_title(f"Chart {chart}. {title}", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100, format="png", **png_options())
    plt.close(fig)


def run_plan(cfg: StationConfig, out: Path, console: Console, plan: DayPlan | None = None
             ) -> dict:
    """Write the charts, the table and the implied times into ``out``; show them."""
    plan = plan or DayPlan()
    out.mkdir(parents=True, exist_ok=True)
    rows = accuracy_table(cfg, plan)
    implied = implied_times(cfg, plan)
    with atomic_path(out / "accuracy.csv") as tmp, open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    for chart in CHARTS:
        with atomic_path(out / f"chart_{chart}.png") as tmp:
            chart_png(chart, rows, tmp, cfg.plan.requirements())
    doc = {"requirements": cfg.plan.model_dump(), **implied}
    with atomic_path(out / "times.json") as tmp:
        tmp.write_text(json.dumps(doc, indent=2, sort_keys=True) + "\n")
    cols = [Column(n, right=n in ("time", "sigma")) for n in
            ("chart", "quantity", "gate", "levels", "time", "sigma", "units")]
    print_fitted(console, "Predicted accuracy against collection time (Charts II-18..II-24)",
                 cols, [[r["chart"], r["quantity"], r["gate"],
                         "yes" if r["level_corrected"] else "no",
                         f"{r['time']:g} {r['time_units']}", f"{r['sigma']:.3g}", r["units"]]
                        for r in rows])
    if "refused" in implied:
        console.print(f"[red]refused:[/] {implied['refused']}")
    else:
        for gate, s in implied["gates"].items():
            units = REQUIREMENT_TEXT[s["requirement"]][0]
            console.print(f"{gate}: {s['chosen']:g} {s['units']} ({s['why']}; predicted "
                          f"{s['predicted']:.3g} {units} for {s['requirement']} "
                          f"{s['required']:g})")
    return doc
