"""A campaign's summary: per constant (and grid point) the observed rms error against the
predicted sigma, with the chi-square interval the ratio keeps for the number of tasks.

With honest sigmas each z = error / sigma is a standard normal draw, so sum(z^2) over n
tasks follows chi^2(n): the ratio sqrt(mean z^2) (observed rms error over predicted sigma,
1 expected) lies in [sqrt(chi2(0.005; n) / n), sqrt(chi2(0.995; n) / n)] 99 % of the time.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

LEVEL = 0.99


def interval(n: int, level: float = LEVEL) -> tuple[float, float]:
    """The ``level`` interval of sqrt(chi^2(n) / n)."""
    a = (1.0 - level) / 2.0
    lo, hi = stats.chi2.ppf([a, 1.0 - a], n)
    return math.sqrt(lo / n), math.sqrt(hi / n)


ESTIMATORS = ("closed_form", "all_positions")  # the rows' z_<estimator> columns (issue 19)


def _by_estimator(g: pd.DataFrame, estimators: list[str]) -> dict[str, Any]:
    """Per estimator: its ratio sqrt(mean z^2), inside its 99 % interval, max |z|."""
    line: dict[str, Any] = {}
    for e in estimators:
        z = g[f"z_{e}"].to_numpy(float)
        z = z[np.isfinite(z)]
        line.update({f"n_{e}": len(z), f"ratio_{e}": math.nan, f"inside_{e}": None,
                     f"max_abs_z_{e}": math.nan})
        if len(z):
            lo, hi = interval(len(z))
            ratio = float(np.sqrt(np.mean(z ** 2)))
            line.update({f"ratio_{e}": ratio, f"inside_{e}": bool(lo <= ratio <= hi),
                         f"max_abs_z_{e}": float(np.max(np.abs(z)))})
    return line


def summarise(rows: pd.DataFrame, grid: list[str]) -> pd.DataFrame:
    """One line per grid point and constant: n, rms error, rms sigma, ratio, its interval,
    inside, max |z| (ratio and interval empty for a constant without sigma); with rows that
    carry both estimators (issue 19), each one's n, ratio, inside and max |z| too."""
    cols = [*grid, "instrument", "parameter", "units", "n", "rms_error", "rms_sigma",
            "ratio", "low", "high", "inside", "max_abs_z"]
    estimators = [e for e in ESTIMATORS if f"z_{e}" in rows.columns]
    cols += [f"{k}_{e}" for e in estimators for k in ("n", "ratio", "inside", "max_abs_z")]
    if rows.empty:
        return pd.DataFrame(columns=cols)
    out = []
    for key, g in rows.groupby([*grid, "instrument", "parameter"], sort=False, dropna=False):
        err = g["error"].to_numpy(float)
        err = err[np.isfinite(err)]
        z = g["z"].to_numpy(float)
        z = z[np.isfinite(z)]
        sig = g["sigma"].to_numpy(float)
        sig = sig[np.isfinite(sig)]
        line: dict[str, Any] = dict(zip([*grid, "instrument", "parameter"], key, strict=True))
        line.update(units=g["units"].iloc[0], n=len(g),
                    rms_error=float(np.sqrt(np.mean(err ** 2))) if len(err) else math.nan,
                    rms_sigma=float(np.sqrt(np.mean(sig ** 2))) if len(sig) else math.nan,
                    ratio=math.nan, low=math.nan, high=math.nan, inside=None,
                    max_abs_z=math.nan)
        if len(z):
            lo, hi = interval(len(z))
            ratio = float(np.sqrt(np.mean(z ** 2)))
            line.update(ratio=ratio, low=lo, high=hi, inside=bool(lo <= ratio <= hi),
                        max_abs_z=float(np.max(np.abs(z))))
        line.update(_by_estimator(g, estimators))
        out.append(line)
    return pd.DataFrame(out, columns=cols)


def write_summary(out: Path, summary: pd.DataFrame, failures: pd.DataFrame,
                  meta: dict[str, Any]) -> None:
    """summary.csv (the table) and summary.json (the table, the failures, the counts)."""
    summary.to_csv(out / "summary.csv", index=False)
    doc = {**meta, "level": LEVEL,
           "constants": json.loads(summary.to_json(orient="records")),
           "failures": [] if failures.empty else json.loads(
               failures[["task", "seed", "message"]].to_json(orient="records"))}
    (out / "summary.json").write_text(json.dumps(doc, indent=1))
