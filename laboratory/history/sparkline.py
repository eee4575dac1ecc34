"""The trend of one constant as an inline SVG sparkline, for the History section's table:
each calibration's estimate with its 1-sigma bar, oldest first, scaled to its own row, the
last point (this run) marked and flagged changes drawn red. Plain SVG markup, so the report
needs no plotting library and stays a few hundred bytes per row."""

from __future__ import annotations

import math
from html import escape

from laboratory.history.trend import Trend

WIDTH = 120  # px of the sparkline
HEIGHT = 26
PAD = 3  # px kept clear at each edge (the marked point's radius)


def _n(v: float) -> str:
    """A coordinate to 0.1 px, without a trailing .0."""
    s = f"{v:.1f}"
    return s[:-2] if s.endswith(".0") else s


def _pm(estimate: float, sigma: float) -> str:
    """``estimate ± sigma`` with the estimate's digits down to the sigma's second."""
    digits = 2
    if estimate != 0.0:
        digits = math.floor(math.log10(abs(estimate))) - math.floor(math.log10(sigma)) + 2
    return f"{estimate:.{min(max(digits, 2), 15)}g} ± {sigma:.2g}"


def sparkline(t: Trend, last: str = "this run") -> str:
    """The SVG of ``t``'s points (x: calibration number; y: estimate, up is larger, the
    row's span from the lowest lower bar to the highest upper bar); its <title> names the
    constant and lists the n points, the last one being ``last``."""
    pts = t.points
    lo = min(p.estimate - p.sigma for p in pts)
    hi = max(p.estimate + p.sigma for p in pts)
    span = hi - lo if hi > lo else 1.0
    step = (WIDTH - 2 * PAD) / max(len(pts) - 1, 1)

    def y(v: float) -> str:
        return _n(HEIGHT - PAD - (v - lo) / span * (HEIGHT - 2 * PAD))

    xs = [_n(PAD + i * step) for i in range(len(pts))]
    ys = [y(p.estimate) for p in pts]
    bars = "".join(f"M{x} {y(p.estimate + p.sigma)}V{y(p.estimate - p.sigma)}"
                   for x, p in zip(xs, pts, strict=True))
    line = "M" + "L".join(f"{x} {v}" for x, v in zip(xs, ys, strict=True))
    red = "".join(f"M{xs[i]} {ys[i]}L{xs[i + 1]} {ys[i + 1]}"
                  for i, c in enumerate(t.changes) if c.flagged)
    units = f" ({t.units})" if t.units else ""
    listed = "; ".join(_pm(p.estimate, p.sigma) for p in pts)
    title = (f"{t.name}{units}: {len(pts)} calibrations oldest first (the last is {last}), "
             f"with 1-sigma bars: {listed}")
    now = ' class="now"'
    dots = "".join(f'<circle{now if i == len(pts) - 1 else ""} cx="{x}" cy="{v}" '
                   f'r="{3 if i == len(pts) - 1 else 2}"/>'
                   for i, (x, v) in enumerate(zip(xs, ys, strict=True)))
    return (f'<svg class="spark" width="{WIDTH}" height="{HEIGHT}" role="img">'
            f"<title>{escape(title)}</title><path class=\"bar\" d=\"{bars}\"/>"
            f'<path class="line" d="{line}"/>'
            + (f'<path class="flag" d="{red}"/>' if red else "") + dots + "</svg>")
