"""The History section's sparkline (laboratory/history/sparkline.py): the exact SVG of a
constant's three calibrations, scaled to its row, the last marked, a flagged change red."""

from __future__ import annotations

from laboratory.history.sparkline import sparkline
from laboratory.history.trend import Point, Trend, _analyse, z_limit


def trend(*xs: float) -> Trend:
    """gyro1 R over calibrations with estimates ``xs``, each of sigma 0.1."""
    t = Trend("gyro1", "R", "deg/h", [Point(f"r{i}", "2026-01-01", f"runs/d{i}", x, 0.1)
                                      for i, x in enumerate(xs)])
    _analyse(t, z_limit(0.999), 0.999)
    return t


def test_the_svg_of_three_calibrations() -> None:
    """Rows span 0.9 .. 2.1 over y 23 .. 3: 1.0 at 21.3, 2.0 at 4.7, 1.5 at 13; the first
    change (z 7.07) is red, the second (z -3.54) too; the last point is this run."""
    assert sparkline(trend(1.0, 2.0, 1.5), "the latest") == (
        '<svg class="spark" width="120" height="26" role="img"><title>gyro1 R (deg/h): 3 '
        "calibrations oldest first (the last is the latest), with 1-sigma bars: 1 ± 0.1; "
        "2 ± 0.1; 1.5 ± 0.1</title>"
        '<path class="bar" d="M3 19.7V23M60 3V6.3M117 11.3V14.7"/>'
        '<path class="line" d="M3 21.3L60 4.7L117 13"/>'
        '<path class="flag" d="M3 21.3L60 4.7M60 4.7L117 13"/>'
        '<circle cx="3" cy="21.3" r="2"/><circle cx="60" cy="4.7" r="2"/>'
        '<circle class="now" cx="117" cy="13" r="3"/></svg>')


def test_no_red_without_a_flag_and_the_title_lists_every_point() -> None:
    s = sparkline(trend(1.0, 1.05, 0.98, 1.02), "this run")
    assert 'class="flag"' not in s and s.count("<circle") == 4
    assert ("4 calibrations oldest first (the last is this run), with 1-sigma bars: 1 ± 0.1; "
            "1.05 ± 0.1; 0.98 ± 0.1; 1.02 ± 0.1</title>") in s
