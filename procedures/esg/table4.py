"""Table 4 of report 004 and the polynomial order trials of its data reduction.

Table 4 ("Readout Test Results"): for each calibration schedule, the calibration and the
readout errors combined as rms, average of absolute values, the largest single error and
its ratio to the 15 arc-second goal. Here each is given for the measured error (against
the assigned colatitude, as the report had it) and, where known, the true one.

Order trials ("Data Reduction Technique"): "Polynomials ranging from the fifth through the
ninth order were calibrated and the residual error was determined. The seventh order
polynomial resulted in good accuracy"; eq. 11's text: "Trial solutions with higher order
polynomials did not significantly improve the resultant calibration". The fit's own
residuals always fall with order (and at 9th order on 24 points they follow the noise:
readout errors between the 5-degree points grow), so the choice by the residuals uses the
leave-one-out (prediction) residuals of the calibration points: each interior point read
out by the fit of the others (the two outermost are left in, as a readout never reaches
beyond the fitted count-ratio range). It is the lowest order within ``SIGNIFICANT`` (10 %) of the
smallest prediction rms over the trials.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence

import numpy as np

from procedures.esg.calibration import Point, ScheduleResult, calibrate, in_schedule
from procedures.esg.chebyshev_fit import fit_deviation
from procedures.esg.mechanization import Mechanization

ORDERS = (5, 6, 7, 8, 9)  # the report's trials
REPORT_ORDER = 7
SIGNIFICANT = 0.10  # a higher order must lower the prediction rms by more than this


def error_stats(errors: Iterable[float | None], goal_arcsec: float) -> dict[str, float | None]:
    """rms, average absolute, largest (by magnitude, signed) and largest/goal of errors
    (arcsec); None for each when there are none (the truth of a served run)."""
    v = [float(x) for x in errors if x is not None]
    if not v:
        return {"rms_arcsec": None, "mean_abs_arcsec": None, "largest_arcsec": None,
                "largest_over_goal": None}
    big = max(v, key=abs)
    return {"rms_arcsec": math.sqrt(sum(x * x for x in v) / len(v)),
            "mean_abs_arcsec": sum(abs(x) for x in v) / len(v),
            "largest_arcsec": big, "largest_over_goal": abs(big) / goal_arcsec}


def table4(results: Sequence[ScheduleResult], goal_arcsec: float) -> list[dict]:
    """Table 4: one row per schedule and data set (calibration, readout), measured and
    true errors (rows' ``error_arcsec`` and ``true_error_arcsec``)."""
    out: list[dict] = []
    for res in results:
        for data, rows in (("calibration", res.calibration), ("readout", res.readout)):
            row: dict = {"schedule": res.name, "data": data, "order": res.fit.order,
                         "n": len(rows)}
            row.update(error_stats((r["error_arcsec"] for r in rows), goal_arcsec))
            true = error_stats((r.get("true_error_arcsec") for r in rows), goal_arcsec)
            row.update({f"true_{k}": v for k, v in true.items()})
            out.append(row)
    return out


def residual_sigma(res: ScheduleResult) -> float:
    """Residual standard error (arcsec) of a schedule's fit: sqrt(SS / (n - order - 1))."""
    e = [r["error_arcsec"] for r in res.calibration]
    dof = len(e) - res.fit.order - 1
    return math.sqrt(sum(x * x for x in e) / dof) if dof > 0 else float("nan")


def prediction_rms(points: list[Point], params: Mechanization, schedule: str,
                   order: int) -> float:
    """rms (arcsec) of the leave-one-out residuals of a schedule's interior calibration
    points (not the smallest and largest count ratio)."""
    fit_pts = [p for p in points if in_schedule(p, schedule)]
    cr = np.array([p.cr for p in fit_pts])
    th = np.array([p.colatitude_deg for p in fit_pts])
    errs = []
    for i in range(len(fit_pts)):
        if cr[i] in (cr.min(), cr.max()):
            continue
        keep = np.arange(len(fit_pts)) != i
        fit = fit_deviation(cr[keep], th[keep], params, order=order)
        errs.append((float(fit.colatitude(cr[i:i + 1])[0]) - th[i]) * 3600.0)
    return math.sqrt(sum(e * e for e in errs) / len(errs))


def order_trials(points: list[Point], params: Mechanization, schedules: Sequence[str],
                 truth: Callable[[ScheduleResult], None] | None = None,
                 orders: Sequence[int] = ORDERS, goal_arcsec: float = 15.0) -> list[dict]:
    """Fit each schedule at each order; the residuals (and, with ``truth``, which adds the
    true errors to a result's rows, the true errors) per order."""
    rows: list[dict] = []
    for s in schedules:
        for n in orders:
            res = calibrate(points, params, s, order=n)
            if truth is not None:
                truth(res)
            cal = error_stats((r["error_arcsec"] for r in res.calibration), goal_arcsec)
            rd = error_stats((r["error_arcsec"] for r in res.readout), goal_arcsec)
            tcal = error_stats((r.get("true_error_arcsec") for r in res.calibration),
                               goal_arcsec)
            trd = error_stats((r.get("true_error_arcsec") for r in res.readout), goal_arcsec)
            rows.append({"schedule": s, "order": n, "n_fit": len(res.calibration),
                         "n_readout": len(res.readout),
                         "residual_sigma_arcsec": residual_sigma(res),
                         "prediction_rms_arcsec": prediction_rms(points, params, s, n),
                         "calibration_rms_arcsec": cal["rms_arcsec"],
                         "readout_rms_arcsec": rd["rms_arcsec"],
                         "true_calibration_rms_arcsec": tcal["rms_arcsec"],
                         "true_readout_rms_arcsec": trd["rms_arcsec"]})
    for s in schedules:
        mine = [r for r in rows if r["schedule"] == s]
        chosen = residual_choice(mine)
        for r in mine:
            r["chosen_by_residuals"] = r["order"] == chosen
    return rows


def residual_choice(trials: Sequence[dict]) -> int:
    """The lowest order whose prediction rms no order betters by more than SIGNIFICANT
    (the report's "did not significantly improve the resultant calibration")."""
    best = min(t["prediction_rms_arcsec"] for t in trials)
    ok = [t["order"] for t in trials
          if (1.0 - SIGNIFICANT) * t["prediction_rms_arcsec"] <= best]
    return int(min(ok))
