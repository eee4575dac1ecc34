"""One campaign task: the command on its virtual station, and one row per constant.

The task runs in a fresh temporary directory through the run functions of
``laboratory.virtual`` (the virtual station with dotted-path overrides the pytest plugin also
uses), so its rows depend on the spec and the task only. A refusal or a stop is the
task's failure (its one-line message), not a Dask error: retrying it would fail again.
"""

from __future__ import annotations

import math
import os
import socket
import tempfile
import time
from pathlib import Path
from typing import Any

from laboratory.campaign.spec import LAB_PREFIX, PLAN_PREFIX, CampaignSpec, Task, lab_rng

Row = dict[str, Any]
# both estimators of the Calibration Results Sheet (issue 19), NaN where a row has none
ESTIMATOR_COLUMNS = ("closed_form", "closed_form_sigma", "all_positions",
                     "all_positions_sigma", "cramer_rao_sigma")


def _num(x: Any) -> float:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) else math.nan


def _row(instrument: str, parameter: str, units: str, estimate: Any, truth: Any,
         sigma: Any, error: Any = None) -> Row:
    est, tru, sig = _num(estimate), _num(truth), _num(sigma)
    err = _num(error) if error is not None else est - tru
    return {"instrument": instrument, "parameter": parameter, "units": units,
            "estimate": est, "truth": tru, "error": err, "sigma": sig,
            "z": err / sig if sig > 0 else math.nan}


def _estimators(row: Row, sheet_row: dict[str, Any], truth: float) -> Row:
    """``row`` with both estimators' estimate and sigma from its sheet row, and their z."""
    for c in ESTIMATOR_COLUMNS:
        row[c] = _num(sheet_row.get(c))
    for e in ("closed_form", "all_positions"):
        err, sig = row[e] - truth, row[f"{e}_sigma"]
        row[f"z_{e}"] = err / sig if sig > 0 else math.nan
    return row


def _sheet_rows(run_dir: Path | None) -> dict[tuple[str, str], dict[str, Any]]:
    """The run's Calibration Results Sheet rows by (instrument, parameter) (none: empty)."""
    import json

    path = None if run_dir is None else run_dir / "sheets" / "calibration_results.json"
    if path is None or not path.is_file():
        return {}
    return {(r["instrument"], r["parameter"]): r
            for r in json.loads(path.read_text()).get("rows") or ()}


def isu_rows(res: dict[str, Any], run_dir: Path | None = None) -> list[Row]:
    """Chart II-5 rows (with both estimators, from the run's sheet), then each alignment's
    errors about east, north and up (truth 0)."""
    sheet = _sheet_rows(run_dir)
    rows = [_estimators(_row(r["instrument"], r["parameter"], r.get("units") or "",
                             r.get("estimate"), r.get("truth"), r.get("sigma"),
                             r.get("error")),
                        sheet.get((r["instrument"], r["parameter"]), {}), _num(r.get("truth")))
            for r in res.get("calibration") or () if isinstance(r, dict)]
    for e in res.get("alignment") or ():
        errs = list(e.get("level_error_arcsec") or (None, None)) + [e.get("azimuth_error_arcsec")]
        for axis, err, sig in zip(("east", "north", "azimuth"), errs,
                                  e.get("predicted_sigma_arcsec") or (None,) * 3, strict=False):
            rows.append(_estimators(_row(f"{e['method']}/{e['estimator']}", axis, "arcsec",
                                         err, 0.0, sig, err), {}, 0.0))
    return rows


def cigtf_rows(res: dict[str, Any], run_dir: Path | None = None) -> list[Row]:
    """Each phase's theta against the true theta; the instabilities delta and Delta."""
    truth = (res.get("truth") or {}).get("theta_arcsec")
    rows = [_row(p["phase"], "theta", "arcsec", p["theta_arcsec"], truth, p["sigma_arcsec"])
            for p in res.get("phases") or ()]
    rows += [_row("operating", "delta", "arcsec", res.get("delta_arcsec"), None, None),
             _row("shutdown", "Delta", "arcsec", res.get("Delta_arcsec"), None, None)]
    return rows


def esg_rows(res: dict[str, Any], run_dir: Path | None = None) -> list[Row]:
    """Per schedule: the assignment rms (an error, truth 0) against its predicted rms; the
    readout and calibration rms against the true ones (no sigma)."""
    rows = []
    for s in res.get("schedules") or ():
        a = s.get("assignment_rms_arcsec")
        rows.append(_row(s["name"], "assignment_rms", "arcsec", a, 0.0,
                         s.get("predicted_assignment_rms_arcsec"), a))
        for q in ("readout", "calibration"):
            rows.append(_row(s["name"], f"{q}_rms", "arcsec", s.get(f"{q}_rms_arcsec"),
                             s.get(f"true_{q}_rms_arcsec"), None))
    return rows


ROWS = {"day": isu_rows, "align": isu_rows, "gyrocompass-test": cigtf_rows,
        "esg-calibration": esg_rows}


def options(spec: CampaignSpec, plan_values: dict[str, Any]) -> dict[str, Any]:
    """The run function's keyword options: the spec's (lists as tuples), the day plan."""
    opts = {k: tuple(v) if isinstance(v, list) else v for k, v in spec.options.items()}
    if plan_values:
        from laboratory.virtual import override
        from procedures.isu.plan import DayPlan

        opts["plan"] = override(opts.get("plan", DayPlan()), plan_values)
    return opts


def station(lab: str, seed: int, over: dict[str, Any], config: Path | None) -> Any:
    """The virtual station of ``lab`` with the task's overrides (laboratory.virtual)."""
    from laboratory.virtual import virtual_station

    return virtual_station(lab, seed, over, config)


def random_station(spec: CampaignSpec, task: Task, over: dict[str, Any]) -> Any:
    """The task's random admissible laboratory (``[laboratory] random``: its own stream,
    ``spec.lab_rng``) over the spec's config, its ``[plan]`` reachable, with the task's
    overrides over it."""
    from laboratory import registry
    from laboratory.isu.random_lab import random_config
    from laboratory.virtual import VirtualStation, override

    lab = registry.get("isu")
    base = lab.load_config(Path(spec.config) if spec.config else None, task.seed)
    cfg, _ = random_config(lab_rng(spec, task.index), task.seed, base,
                           redraw_isu=spec.laboratory.redraw_isu, noise=spec.laboratory.noise)
    return VirtualStation(lab, override(cfg, over), over)


def run_task(spec: CampaignSpec, task: Task) -> dict[str, Any]:
    """Run ``task``; returns index, seed, values, rows, failure (a line or None), wall_s
    and worker (host:pid)."""
    t0 = time.perf_counter()
    rows: list[Row] = []
    failure = None
    try:
        from laboratory.virtual import PROCEDURES

        lab, fn = PROCEDURES[spec.command]
        plan = {k[len(PLAN_PREFIX):]: v for k, v in task.values.items()
                if k.startswith(PLAN_PREFIX)}
        if plan and spec.lab != "isu":
            raise ValueError(f"{', '.join(PLAN_PREFIX + k for k in plan)}: the day plan is "
                             f"the isu laboratory's, not {spec.lab}'s")
        over = {k: v for k, v in task.values.items()
                if not k.startswith((PLAN_PREFIX, LAB_PREFIX))}
        st = (random_station(spec, task, over) if spec.laboratory.random else
              station(lab, task.seed, over, Path(spec.config) if spec.config else None))
        opts = options(spec, plan)
        with tempfile.TemporaryDirectory(prefix="campaign-") as d:
            res = fn(st, Path(d) / "run", opts)
            rows = ROWS[spec.command](res, Path(d) / "run")
    except Exception as e:  # noqa: BLE001 - any refusal or stop is the task's failure
        from laboratory.app import one_line

        failure = f"{type(e).__name__}: {one_line(e)}"
        rows = []
    return {"index": task.index, "seed": task.seed, "values": dict(task.values),
            "rows": rows, "failure": failure, "wall_s": time.perf_counter() - t0,
            "worker": f"{socket.gethostname()}:{os.getpid()}"}


def noop(x: int) -> int:
    """A task that does nothing: Dask's round trip per task (bench/campaign_overhead.py)."""
    return x
