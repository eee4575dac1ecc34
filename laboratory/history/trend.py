"""Trends of a unit's constants across calibrations: the significance of each change and
the turn-on-to-turn-on scatter against the predicted sigma.

For each constant with an estimate and a sigma on two or more completed runs: every change
between consecutive calibrations with z = change / sqrt(sigma_a^2 + sigma_b^2), flagged when
|z| exceeds the two-sided level; and the chi-square of the day-to-day changes (taken with
their correlations, it equals the weighted scatter about the weighted mean, n - 1 degrees of
freedom), flagged when its upper tail probability is below 1 - level.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from statistics import NormalDist
from typing import TYPE_CHECKING, BinaryIO, Protocol

from laboratory.plot_worker import png_options

if TYPE_CHECKING:
    from collections.abc import Sequence


class ResultLike(Protocol):
    """A result row as the trends read it (the store's ResultRow, lite's LiteResult): a
    constant's estimate and sigma, and which constant of which table it is."""

    estimate: float | None
    sigma: float | None
    table: str
    instrument: str
    parameter: str
    units: str | None


class RunLike(Protocol):
    """A run as the trends and the report's section read it (the store's RunRow, lite's
    LiteRun)."""

    run_uid: str
    path: str
    laboratory: str
    date: str
    status: str

    @property
    def results(self) -> Sequence[ResultLike]: ...


DEFAULT_LEVEL = 0.999  # the two-sided level beyond which `station trend` flags
COLUMNS = ("inst", "param", "units", "n", "last change", "z", "max |z|", "chi2/dof", "p",
           "scatter", "pred sigma", "flag")  # the trend table, in `station trend` and the report


@dataclass(frozen=True)
class Point:
    """One calibration of a constant."""

    run_uid: str
    date: str
    path: str
    estimate: float
    sigma: float


@dataclass(frozen=True)
class Change:
    """The change from one calibration to the next and its significance."""

    before: Point
    after: Point
    delta: float
    sigma: float
    z: float
    flagged: bool


@dataclass
class Trend:
    """One constant across the unit's calibrations."""

    instrument: str
    parameter: str
    units: str | None
    points: list[Point] = field(default_factory=list)
    changes: list[Change] = field(default_factory=list)
    chi2: float = math.nan
    dof: int = 0
    p_value: float = math.nan
    scatter: float = math.nan  # sample standard deviation of the estimates
    predicted: float = math.nan  # root mean square of their predicted sigmas
    scatter_flagged: bool = False

    @property
    def name(self) -> str:
        return f"{self.instrument} {self.parameter}".strip()

    @property
    def flagged(self) -> bool:
        return self.scatter_flagged or any(c.flagged for c in self.changes)


def flags(t: Trend) -> list[str]:
    """What a constant's trend is flagged for: CHANGE (a change beyond the level), SCATTER."""
    return (["CHANGE"] if any(c.flagged for c in t.changes) else []) + (
        ["SCATTER"] if t.scatter_flagged else [])


def cells(t: Trend) -> list[str]:
    """A constant's row of the trend table (COLUMNS), as `station trend` and the report
    print it: the latest change and its z, the largest |z|, the scatter's chi-square."""
    last = t.changes[-1]
    return [t.instrument, t.parameter, t.units or "-", str(len(t.points)),
            f"{last.delta:+.3e}", f"{last.z:+.2f}", f"{max(abs(c.z) for c in t.changes):.2f}",
            f"{t.chi2:.2f}/{t.dof}", f"{t.p_value:.3g}", f"{t.scatter:.3e}",
            f"{t.predicted:.3e}", " ".join(flags(t)) or "-"]


def z_limit(level: float) -> float:
    """|z| beyond which a change is significant at the two-sided ``level``: the normal
    quantile, statistics.NormalDist's (Wichura's AS 241, to about 1e-16; scipy.stats, and
    even scipy.special, cost every report with a history 0.6 s and 0.17 s of imports:
    issue 17)."""
    if not 0.0 < level < 1.0:
        raise ValueError(f"--level must lie between 0 and 1, got {level:g}")
    return NormalDist().inv_cdf(0.5 + level / 2.0)


LOG_SPACE_HALF_CHI2 = 700.0  # beyond it exp(-x/2) underflows: the terms from logarithms


def chi2_sf(x: float, dof: int) -> float:
    """P(chi-square with ``dof`` >= 1 degrees of freedom > ``x``): the regularized upper
    incomplete gamma Q(dof/2, x/2) in its closed forms for a whole ``dof`` (for h = x/2,
    even dof = 2k: e^-h sum_{i<k} h^i / i!; odd dof = 2k + 1: erfc(sqrt h) + e^-h sum_{i<k}
    h^(i + 1/2) / Gamma(i + 3/2)), every term positive (no cancellation); to about 1e-14
    of scipy.special.chdtrc over the histories' range (tests/test_history_lite.py), without
    importing scipy (issue 17)."""
    if math.isnan(x):
        return math.nan
    if x <= 0.0:
        return 1.0
    if math.isinf(x):
        return 0.0
    h = 0.5 * x
    k, odd = divmod(dof, 2)
    total = math.erfc(math.sqrt(h)) if odd else 0.0
    first = 0.5 if odd else 0.0  # the power of h of the sum's first term
    if h < LOG_SPACE_HALF_CHI2:
        term = math.exp(-h) * h ** first / math.gamma(first + 1.0)
        for i in range(k):
            total += term
            term *= h / (i + first + 1.0)
        return total
    log_h = math.log(h)
    return total + sum(math.exp((i + first) * log_h - h - math.lgamma(i + first + 1.0))
                       for i in range(k))


def trends(runs: Sequence[RunLike], level: float = DEFAULT_LEVEL) -> list[Trend]:
    """Per constant (table order of its first appearance), the trend over ``runs`` (oldest
    first): only completed runs' determined rows (an estimate and a positive sigma) count."""
    zl = z_limit(level)
    by_key: dict[tuple[str, str, str], Trend] = {}
    for run in runs:
        if run.status != "completed":
            continue
        for r in run.results:
            if r.estimate is None or r.sigma is None or not r.sigma > 0:
                continue
            key = (r.table, r.instrument, r.parameter)
            t = by_key.setdefault(key, Trend(r.instrument, r.parameter, r.units))
            t.points.append(Point(run.run_uid, run.date, run.path, r.estimate, r.sigma))
    out = [t for t in by_key.values() if len(t.points) >= 2]
    for t in out:
        _analyse(t, zl, level)
    return out


def _analyse(t: Trend, zl: float, level: float) -> None:
    for a, b in zip(t.points, t.points[1:], strict=False):
        s = math.hypot(a.sigma, b.sigma)
        z = (b.estimate - a.estimate) / s
        t.changes.append(Change(a, b, b.estimate - a.estimate, s, z, abs(z) > zl))
    w = [1.0 / p.sigma ** 2 for p in t.points]
    mean = sum(wi * p.estimate for wi, p in zip(w, t.points, strict=True)) / sum(w)
    t.chi2 = sum(wi * (p.estimate - mean) ** 2 for wi, p in zip(w, t.points, strict=True))
    t.dof = len(t.points) - 1
    t.p_value = chi2_sf(t.chi2, t.dof)
    t.scatter_flagged = t.p_value < 1.0 - level
    n = len(t.points)
    m = sum(p.estimate for p in t.points) / n
    t.scatter = math.sqrt(sum((p.estimate - m) ** 2 for p in t.points) / (n - 1))
    t.predicted = math.sqrt(sum(p.sigma ** 2 for p in t.points) / n)


def trend_plot(ts: list[Trend], path: Path | BinaryIO, unit: str, level: float) -> None:
    """trend.png (a file, or PNG bytes into a binary stream): one panel per constant, each
    calibration's estimate less the weighted mean with its 1-sigma bar; flagged changes
    drawn red."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    n = max(len(ts), 1)
    cols = min(6, n)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(2.6 * cols, 2.0 * rows + 0.6), squeeze=False)
    for ax in axes.flat[len(ts):]:
        ax.set_visible(False)
    for ax, t in zip(axes.flat, ts, strict=False):
        w = [1.0 / p.sigma ** 2 for p in t.points]
        mean = sum(wi * p.estimate for wi, p in zip(w, t.points, strict=True)) / sum(w)
        x = list(range(1, len(t.points) + 1))
        y = [p.estimate - mean for p in t.points]
        ax.errorbar(x, y, yerr=[p.sigma for p in t.points], fmt="o", ms=3, color="C0")
        for i, c in enumerate(t.changes):
            ax.plot([x[i], x[i + 1]], [y[i], y[i + 1]], color="red" if c.flagged else "0.6",
                    lw=1.5 if c.flagged else 0.8)
        ax.axhline(0.0, color="0.8", lw=0.5)
        colour = "red" if t.flagged else "black"
        ax.set_title(f"{t.name} ({t.units or '-'})", fontsize=8, color=colour)
        ax.tick_params(labelsize=6)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # calibration number
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 3))
        ax.yaxis.get_offset_text().set_fontsize(6)
    fig.suptitle(f"{unit}: estimate less weighted mean per calibration (1 sigma bars; red: "
                 f"beyond the {level:g} level)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90, format="png", **png_options())
    plt.close(fig)
