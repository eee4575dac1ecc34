"""`station plan --verify`: the predicted accuracy curves beside the same curves measured by
a campaign (issue 18).

For each study (a constant and the gate whose collection time it depends on) a campaign of
partial days (only the charts that measure the constant) runs N seeds at each of several
collection times, the gate fixed for the study (DayPlan.study_*; turns by min_turns). Per
time and instrument: the predicted sigma (procedures.isu.accuracy.Predictor over a nominal
day with that time), the observed rms error of the N days against the simulator's truth,
their ratio and its 99 % chi-square interval for N seeds. Written: verify.csv, one
verify_<chart>.png per study, the campaigns under campaign-<chart>/.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from rich.console import Console

from laboratory.campaign.summary import LEVEL, interval
from laboratory.plot_worker import png_options
from laboratory.tables import Column, print_fitted
from procedures.isu.accuracy import (
    DAY_TURNING_FIRST_S,
    DAY_TURNING_GAPS_S,
    GATE_UNITS,
    Predictor,
)
from procedures.isu.plan import DayPlan
from station.config.assignment import named_item
from station.config.isu import StationConfig
from station.files import atomic_path


@dataclass(frozen=True)
class Study:
    """One constant against one gate's collection time, and the cheapest charts measuring it."""

    chart: str  # the report's chart (II-18..II-24)
    title: str
    parameter: str  # the Chart II-5 row's parameter, for gyro1..3 or accel1..3
    kind: str  # "gyro" | "accel"
    gate: str  # procedures.isu.accuracy.GATES
    path: str  # the DayPlan field the campaign sweeps
    only: tuple[str, ...]
    times: tuple[float, ...]


STUDIES: dict[str, Study] = {s.chart: s for s in (
    Study("II-18", "Gyro scale factor DeltaPhi against turns", "DeltaPhi", "gyro",
          "gyro 1-6", "min_turns", ("II-6",), (1, 2, 4, 7, 10)),
    Study("II-19", "Gyro drift R against the gyro gate", "R", "gyro", "gyro 7-15",
          "study_gyro_gate_s", ("II-6", "II-11"), (60.0, 150.0, 300.0, 600.0, 1200.0)),
    Study("II-24", "Accelerometer bias D0 against the horizontal gate (level corrections)",
          "D0", "accel", "accel horizontal", "study_accel_horizontal_s", ("II-13", "II-14"),
          (120.0, 300.0, 600.0, 1200.0, 1800.0)),
)}
COLUMNS = ("chart", "instrument", "parameter", "units", "time", "time_units", "n",
           "predicted", "observed", "ratio", "low", "high", "inside")


def study_spec(study: Study, seeds: int, seed: int, times: tuple[float, ...] | None,
               config: Path | None) -> Any:
    """The campaign of one study: partial days over its times (grid) times ``seeds``."""
    from laboratory.campaign.spec import PLAN_PREFIX, CampaignSpec

    pts: list[float | int] = [int(t) if study.gate == "gyro 1-6" else float(t)
                              for t in (times or study.times)]
    return CampaignSpec(command="day", seeds=seeds, seed=seed,
                        config=str(config) if config else None,
                        options={"only": list(study.only), "align": False},
                        grid={PLAN_PREFIX + study.path: pts})


def predictor(cfg: StationConfig, plan: DayPlan | None = None) -> Predictor:
    """The covariance model of `station plan` for this station (its noise, site, clock)."""
    from laboratory.isu.spec import mounting, noise_spec, site_of
    from procedures.isu.settings import manual_times, planning_lab

    plan = (plan or DayPlan()).model_copy(update={"requirements": cfg.plan})
    lab = planning_lab(plan, site_of(cfg), noise_spec(cfg), f0=cfg.isu.accels[0].f0_hz,
                       t_bi=mounting(cfg))
    # positions 1-6 at the instants the campaign's days run them (the pier's 60 s wobble
    # correlates a pair's gates through their spacing; procedures.isu.accuracy)
    lab = replace(lab, turning_first_s=DAY_TURNING_FIRST_S, turning_gaps_s=DAY_TURNING_GAPS_S)
    return Predictor(lab, manual_times(plan))


def verify_table(study: Study, rows: pd.DataFrame, pred: Predictor) -> list[dict[str, Any]]:
    """One line per collection time and instrument: predicted sigma (Predictor), observed
    rms error over the campaign's days, their ratio and its chi-square interval."""
    from laboratory.campaign.spec import PLAN_PREFIX

    col = PLAN_PREFIX + study.path
    out = []
    sel = rows[rows["parameter"] == study.parameter]
    for t in sorted(sel[col].unique()):
        cov = pred.covariance(pred.default.set(study.gate, float(t)))
        at = sel[sel[col] == t]
        for k in (1, 2, 3):
            inst = f"{study.kind}{k}"
            g = at[at["instrument"] == inst]
            err = g["error"].to_numpy(float)
            err = err[np.isfinite(err)]
            if not len(err):
                continue
            p = pred.sigma(cov, inst, study.parameter)
            obs = float(np.sqrt(np.mean(err ** 2)))
            lo, hi = interval(len(err))
            ratio = obs / p
            out.append({"chart": study.chart, "instrument": inst,
                        "parameter": study.parameter, "units": str(g["units"].iloc[0]),
                        "time": float(t), "time_units": GATE_UNITS[study.gate],
                        "n": len(err), "predicted": p, "observed": obs, "ratio": ratio,
                        "low": lo, "high": hi, "inside": bool(lo <= ratio <= hi)})
    return out


def verify_png(study: Study, table: list[dict[str, Any]], path: Path) -> None:
    """Predicted sigma against time (lines) and the observed rms error (points), its bars
    the 99 % chi-square interval of the true sigma from N seeds (the line crosses a bar
    exactly when the ratio is inside its interval), log-log."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for k, colour in zip((1, 2, 3), ("C0", "C1", "C2"), strict=True):
        pts = [r for r in table if r["instrument"] == f"{study.kind}{k}"]
        if not pts:
            continue
        x = np.array([r["time"] for r in pts]) * (1.03 ** (k - 2))  # side by side
        pred = np.array([r["predicted"] for r in pts])
        obs = np.array([r["observed"] for r in pts])
        lo = np.array([r["low"] for r in pts])
        hi = np.array([r["high"] for r in pts])
        ax.plot([r["time"] for r in pts], pred, "-", color=colour,
                label=f"{study.kind}{k} predicted")
        # the true sigma's interval from N errors: the prediction inside it <=> ratio inside
        ax.errorbar(x, obs, yerr=[obs - obs / hi, obs / lo - obs], fmt="o", color=colour,
                    capsize=3,
                    label=f"{study.kind}{k} observed rms")
    n = table[0]["n"] if table else 0
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(f"collection time ({GATE_UNITS[study.gate]})")
    ax.set_ylabel(f"{study.parameter} error, 1 sigma ({table[0]['units'] if table else ''})")
    ax.set_title(f"Chart {study.chart}: {study.title}\n{n} seeds per time; bars: "
                 f"{100 * LEVEL:g} % chi-square interval", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110, **png_options())
    plt.close(fig)


def run_verify(cfg: StationConfig, out: Path, console: Console, *, seeds: int, seed: int,
               times: dict[str, tuple[float, ...]] | None = None, charts: tuple[str, ...]
               | None = None, scheduler: str | None = None, workers: int | None = None,
               config: Path | None = None, quiet: bool = True) -> list[dict[str, Any]]:
    """Run each study's campaign into ``out`` (resuming what is stored), then write
    verify.csv and the PNGs and show the table."""
    from laboratory.campaign.run import run_campaign
    from laboratory.campaign.store import CampaignStore

    out.mkdir(parents=True, exist_ok=True)
    pred = predictor(cfg)
    table: list[dict[str, Any]] = []
    for chart in charts or tuple(STUDIES):
        study = STUDIES[chart]
        spec = study_spec(study, seeds, seed, (times or {}).get(chart), config)
        camp = out / f"campaign-{chart}"
        run_campaign(spec, camp, scheduler=scheduler, workers=workers,
                     resume=(camp / "campaign.json").is_file(), console=console, quiet=quiet)
        part = verify_table(study, CampaignStore(camp).table("rows"), pred)
        with atomic_path(out / f"verify_{chart}.png") as tmp:
            verify_png(study, part, tmp)
        table += part
    with atomic_path(out / "verify.csv") as tmp, open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(COLUMNS))
        w.writeheader()
        w.writerows(table)
    cols = [Column(n, right=n not in ("chart", "constant", "inside")) for n in
            ("chart", "constant", "time", "n", "predicted", "observed", "ratio", "interval",
             "inside")]
    print_fitted(console, "Predicted sigma against the observed rms error (station plan "
                 "--verify)", cols,
                 [[r["chart"], f"{r['instrument']} {r['parameter']} ({r['units']})",
                   f"{r['time']:g} {r['time_units']}", str(r["n"]), f"{r['predicted']:.3g}",
                   f"{r['observed']:.3g}", f"{r['ratio']:.3f}",
                   f"{r['low']:.2f}..{r['high']:.2f}", "yes" if r["inside"] else "NO"]
                  for r in table])
    return table


def parse_times(items: list[str] | None) -> dict[str, tuple[float, ...]]:
    """``--times CHART=T1,T2,...`` items (ValueError naming a bad item)."""
    got: dict[str, tuple[float, ...]] = {}
    for item in items or ():
        chart, text = named_item("--times", item, STUDIES, "give CHART=T1,T2,... with "
                                 f"CHART one of {', '.join(STUDIES)}")
        try:
            vals = tuple(float(v) for v in text.split(",") if v.strip())
        except ValueError:
            raise ValueError(f"--times {chart}: {text!r} is not a list of numbers") from None
        if not vals or not all(math.isfinite(v) and v > 0 for v in vals):
            raise ValueError(f"--times {chart}: {text!r}: give positive times")
        if STUDIES[chart].gate == "gyro 1-6" and any(v != int(v) for v in vals):
            raise ValueError(f"--times {chart}: turns are whole numbers, got {text!r}")
        got[chart] = vals
    return got



def check_options(seeds: int, workers: int | None, scheduler: str | None) -> None:
    """ValueError naming a --verify option out of range."""
    if seeds < 2:
        raise ValueError(f"--seeds must be 2 or more (an rms needs several days), got {seeds}")
    if workers is not None and workers < 0:
        raise ValueError(f"--workers must be 0 or more, got {workers}")
    if scheduler is not None and workers is not None:
        raise ValueError("--workers sizes the embedded cluster; not with --scheduler")
