"""Readout-strategy study: error amplification of line-edge uncertainty (report 004, Fig. 2).

Per-pickoff error (derivation)
------------------------------
A pickoff at colatitude th measures mu = ph2 - ph1, the longitude between the trailing
edges of line 1 and line 2 on the parallel th. The two lines are mirror images ("equal and
opposite slopes"), so along line 1 d(mu)/d(th) = -2 d(ph1)/d(th), and the colatitude is
inferred from mu alone. Let psi be the angle between a line and the parallel and
T = |d th / d ph| along the line; on the sphere the parallel's arc is sin(th) d ph, so
tan(psi) = T / sin(th). An edge displaced by delta normal to itself (on the surface, r = 1)
crosses the parallel delta / sin(psi) further along it, i.e. its longitude moves by
delta / (sin(psi) sin(th)). The two trailing edges are independent with sigma e, hence
sigma(mu) = sqrt(2) e / (sin(psi) sin(th)). With alpha = cos th, |d alpha / d mu| =
sin(th) T / 2, and sin(psi) = T / sqrt(sin^2 th + T^2):

    sigma(alpha) = T e / (sqrt(2) sin(psi)) = (e / sqrt 2) sqrt(sin^2 th + T^2)

(equivalently: one edge moving by delta shifts that line by delta / cos(psi) in colatitude,
which mu reads as half of it, so sigma(th) = e / (sqrt 2 cos psi), sigma(alpha) =
sin(th) sigma(th)). With n sets of lines the n readings average: divide the variance by n.

* great circle b sin th sin ph + c cos th = 0: T^2 = sin^2 th (b^2 sin^2 th - c^2 cos^2 th)
  / c^2, so sin^2 th + T^2 = sin^4 th / c^2 and sigma(alpha) = e (1 - alpha^2) / (sqrt 2 c),
  largest at the equator (cos psi = c / sin th);
* cosine cos th = K ph: T = K / sin th, sigma(alpha)^2 = (e^2 / 2) (1 - alpha^2 + K^2 /
  (1 - alpha^2)).

The report (repeating its 1968 study) prints for the cosine pattern (garbled; this is our
reading of the OCR),
sigma(alpha) = (e / r) sqrt((1 / 2n) (K^2 / (1 - alpha^2) + 1)) with K = 2n cos(th0) / pi,
and after eq. (3) sigma^2(dS) = (e^2 / r^2) (6 n cos^2 th0 / pi^2 + 1 / n), independent of
orientation. That "+1" where the sphere gives "+ (1 - alpha^2)" is what one gets by taking
the line angle in the flat (longitude, colatitude) chart, tan(psi) = T, while converting
arc to longitude with sin(th): sigma(alpha)^2 = (e^2 / 2)(1 + T^2). Only that form makes
the normalised three-pickoff error orientation-independent (sum (1 - alpha^2) = 2 gives
(e^2 / 2n)(2 + 3 K^2)), which the report states; with the sphere form it is not. The
report's spacing rule (sin(delta) from tan(delta) = d th / d ph, Figure 1 text) uses the
same chart angle. ``convention="chart"`` reproduces those assumptions; "sphere" (default)
is the geometry as derived above.

Pattern geometry from the range (Figure 1 spacing rule, n = 1)
--------------------------------------------------------------
Line 0.012, logic line 0.024, gap 0.048: the logic line and its neighbour are 0.060 apart
normal to the lines, x = 0.060 / sin(delta) along the parallel at the extremity, delta the
line's angle to the parallel there. 5 x is shared by the four half lines, so 1.25 x
(longitude 1.25 x / (r sin th0)) comes off each half line's allotment pi / (2n):
ph0 = pi / (2n) - 1.25 x / (r sin th0), where ph0 is the extremity's longitude from the
equator crossing. The great circle through (90 deg, 0) and (th0, ph0) has
tan i = cot(th0) / sin(ph0); the cosine pattern K = cos(th0) / ph0. Both are solved
together with delta (which depends on i or K) by a 1-D root find.

Amplification (ordinate of Figure 2)
------------------------------------
Orthogonal pickoffs, spin vector uniform on the sphere (Fibonacci lattice, 20000 points).
A pickoff views the pattern when th0 <= th <= 180 - th0. Two-pickoff strategy: the two
nearest the equator, eq. (2). Mixed: eq. (3) with all three when all three view, else
eq. (2) with the two that do. Ordinate: RMS over orientations of sqrt(eq.)/e, i.e.
sqrt(mean(eq.)) / e. Orientations with fewer than two viewing pickoffs (possible only
for th0 > 45 deg, where two cosines can both exceed cos th0) are excluded and their
fraction is reported; the curves mean something only for th0 <= 45 deg.

Results (figure2_table; range = th0, the pattern grows as th0 falls; Fibonacci 20000)
-----------------------------------------------------------------------------------
th0 (deg)                     45     43     41     39     37     35     33     30
sphere  great circle, two    1.377  1.432  1.493  1.562  1.639  1.727  1.827  2.006
        great circle, mixed  1.345  1.384  1.428  1.479  1.537  1.605  1.684  1.829
        cosine, two          1.194  1.205  1.216  1.227  1.238  1.249  1.260  1.278
        cosine, mixed        1.160  1.155  1.151  1.150  1.151  1.153  1.157  1.167
chart   great circle, two    1.477  1.534  1.599  1.674  1.759  1.858  1.974  2.188
        great circle, mixed  1.439  1.477  1.524  1.579  1.645  1.723  1.817  1.995
        cosine, two          1.291  1.302  1.313  1.323  1.334  1.345  1.356  1.372
        cosine, mixed        1.251  1.243  1.237  1.235  1.235  1.238  1.243  1.253
Geometry at 43 deg (great circle): i = 49.18 deg sphere, 50.11 deg chart; at 37 deg
(cosine): K = 0.5614 sphere, 0.5744 chart. Cosine mixed minimum: th0 = 38.1-38.6 deg in
both conventions (the curve is flat to 0.1 % from 37 to 40 deg).

Report: 1.55 (great circle, 43 deg; the strategy is not stated) and 1.20 (cosine, mixed,
37 deg, minimum "near 37"). With the chart assumptions 1.55 is the two-pickoff curve
(-1 %; the mixed curve gives 1.477, -5 %) and 1.20 is +3 %; with the sphere geometry the
great circle is -8 % (two) / -11 % (mixed) and the cosine -4 %. Both conventions give
the report's shapes: the great-circle curves and the cosine two-pickoff curve grow with
the range, the cosine mixed curve has its minimum near 38 deg. Neither the orientation
distribution (an equal-angle grid about one pickoff moves the values by 1-2 %) nor
RMS-of-sigma against mean-of-sigma (under 0.5 %) explains the sphere/report gap; the
chart-angle assumption brings both report values within 3 %. Edge resolution for
15 arcsec: 15" / 1.55 -> 46.9 micro-inch, 15" / 1.20 -> 60.6 micro-inch (the report's 47
and 60); with the sphere values 15" / 1.432 -> 50.8 and 15" / 1.151 -> 63.2 micro-inch.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq, minimize_scalar

from procedures.esg.readout import nearest_equator_pair, variance_three, variance_two

__all__ = [
    "PATTERNS",
    "STRATEGIES",
    "CONVENTIONS",
    "PatternGeometry",
    "pattern_geometry",
    "pickoff_sigma",
    "fibonacci_sphere",
    "amplification_details",
    "amplification",
    "figure2_table",
    "cosine_mixed_minimum",
    "edge_resolution_microinch",
]

PATTERNS = ("great_circle", "cosine")
STRATEGIES = ("two_pickoff", "mixed")
CONVENTIONS = ("sphere", "chart")

LINE_WIDTH_IN = 0.012
LOGIC_WIDTH_IN = 0.024
GAP_IN = 0.048               # logic line to pattern line, normal to the lines
NORMAL_SPACING_IN = LINE_WIDTH_IN + GAP_IN   # 0.060: x = this / sin(delta)
HALF_LINE_SHARE = 1.25       # 5 x over four half lines
ARCSEC = math.pi / (180.0 * 3600.0)


@dataclass(frozen=True)
class PatternGeometry:
    """One pattern of the study: great circle (inclination i) or cosine (cos th = K ph)."""

    pattern: str
    theta0_deg: float
    convention: str = "sphere"
    n_sets: int = 1
    inclination_deg: float = float("nan")
    k: float = float("nan")
    phi0_deg: float = float("nan")     # extremity longitude from the equator crossing
    delta_deg: float = float("nan")    # line angle to the parallel at the extremity
    x_inch: float = float("nan")       # spacing parameter x of Figure 1

    def slope2(self, alpha: ArrayLike) -> np.ndarray:
        """T^2 = (d th / d ph)^2 along the line where cos th = alpha."""
        s2 = 1.0 - np.square(np.asarray(alpha, dtype=float))
        if self.pattern == "great_circle":
            i = math.radians(self.inclination_deg)
            b, c = math.sin(i), math.cos(i)
            return s2 * np.clip(b * b * s2 - c * c * (1.0 - s2), 0.0, None) / (c * c)
        return self.k * self.k / s2


def _check(pattern: str, convention: str) -> None:
    if pattern not in PATTERNS:
        raise ValueError(f"pattern must be one of {PATTERNS}, not {pattern!r}")
    if convention not in CONVENTIONS:
        raise ValueError(f"convention must be one of {CONVENTIONS}, not {convention!r}")


def _tan_delta(t2: float, sin_th: float, convention: str) -> float:
    t = math.sqrt(t2)
    return t / sin_th if convention == "sphere" else t


def pattern_geometry(pattern: str, theta0_deg: float, convention: str = "sphere",
                     n_sets: int = 1, radius_inch: float = 1.0) -> PatternGeometry:
    """Inclination (great circle) or K (cosine) for a pattern ending at theta0 (Fig. 1 rule)."""
    _check(pattern, convention)
    th0 = math.radians(theta0_deg)
    s0, c0 = math.sin(th0), math.cos(th0)
    allot = math.pi / (2 * n_sets)

    def spacing(geom: PatternGeometry) -> tuple[float, float]:
        td = _tan_delta(float(geom.slope2(c0)), s0, convention)
        x = NORMAL_SPACING_IN * math.sqrt(1.0 + td * td) / td   # 0.060 / sin(delta)
        return x, math.atan(td)

    if pattern == "great_circle":
        def geom_of_i(i: float) -> PatternGeometry:
            return PatternGeometry(pattern, theta0_deg, convention, n_sets,
                                   inclination_deg=math.degrees(i))

        def resid_i(i: float) -> float:
            ph0 = math.asin(min(1.0, c0 / (s0 * math.tan(i))))
            x, _ = spacing(geom_of_i(i))
            return ph0 - (allot - HALF_LINE_SHARE * x / (radius_inch * s0))

        lo = math.pi / 2 - th0
        i = brentq(resid_i, lo + 1e-9, math.pi / 2 - 1e-9, xtol=1e-14)
        g = geom_of_i(i)
        ph0 = math.asin(c0 / (s0 * math.tan(i)))
    else:
        def geom_of_ph0(ph0: float) -> PatternGeometry:
            return PatternGeometry(pattern, theta0_deg, convention, n_sets, k=c0 / ph0)

        def resid_ph0(ph0: float) -> float:
            x, _ = spacing(geom_of_ph0(ph0))
            return ph0 - (allot - HALF_LINE_SHARE * x / (radius_inch * s0))

        ph0 = brentq(resid_ph0, 1e-6, allot, xtol=1e-14)
        g = geom_of_ph0(ph0)
    x, delta = spacing(g)
    return PatternGeometry(g.pattern, theta0_deg, convention, n_sets, g.inclination_deg, g.k,
                           math.degrees(ph0), math.degrees(delta), x)


def pickoff_sigma(geom: PatternGeometry, alpha: ArrayLike) -> np.ndarray:
    """1-sigma of a pickoff's direction cosine per unit edge error e (r = 1).

    sphere: sqrt((sin^2 th + T^2) / 2n); chart (report): sqrt((1 + T^2) / 2n).
    """
    a = np.asarray(alpha, dtype=float)
    base = 1.0 - a * a if geom.convention == "sphere" else np.ones_like(a)
    return np.sqrt((base + geom.slope2(a)) / (2.0 * geom.n_sets))


@lru_cache(maxsize=8)
def _fib(n: int) -> np.ndarray:
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    ph = math.pi * (1.0 + math.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    out = np.stack([r * np.cos(ph), r * np.sin(ph), z], axis=1)
    out.setflags(write=False)
    return out


def fibonacci_sphere(n: int = 20000) -> np.ndarray:
    """n nearly uniform unit vectors (Fibonacci lattice), deterministic."""
    return _fib(int(n))


def _equator_pairs(alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each orientation's two pickoffs nearest the equator and their cosines."""
    pair = nearest_equator_pair(alpha)
    return (pair, np.take_along_axis(alpha, pair[:, :1], 1)[:, 0],
            np.take_along_axis(alpha, pair[:, 1:], 1)[:, 0])


@lru_cache(maxsize=8)
def _lattice_pairs(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``_equator_pairs`` of the n-point Fibonacci lattice, made once: they depend on the
    orientations alone, and a Figure 2 study asks for them some 70 times (issue 17)."""
    out = _equator_pairs(fibonacci_sphere(n))
    for x in out:
        x.setflags(write=False)
    return out


def amplification_details(pattern: str, strategy: str, theta0_deg: float,
                          convention: str = "sphere", points: int = 20000,
                          orientations: np.ndarray | None = None) -> dict:
    """Amplification and its bookkeeping: factor, excluded and three-pickoff fractions."""
    _check(pattern, convention)
    if strategy not in STRATEGIES:
        raise ValueError(f"strategy must be one of {STRATEGIES}, not {strategy!r}")
    geom = pattern_geometry(pattern, theta0_deg, convention)
    s = fibonacci_sphere(points) if orientations is None else np.asarray(orientations, float)
    alpha = s                                          # orthogonal triad: cosines = components
    view = np.abs(alpha) <= math.cos(math.radians(theta0_deg))
    nv = view.sum(axis=1)
    ok = nv >= 2
    var = pickoff_sigma(geom, alpha) ** 2
    pair, a_i, a_j = (_lattice_pairs(int(points)) if orientations is None
                      else _equator_pairs(alpha))
    v_i = np.take_along_axis(var, pair[:, :1], 1)[:, 0]
    v_j = np.take_along_axis(var, pair[:, 1:], 1)[:, 0]
    v = variance_two(a_i, a_j, v_i, v_j)
    if strategy == "mixed":
        v = np.where(nv == 3, variance_three(alpha, var), v)
    return {
        "factor": float(math.sqrt(v[ok].mean())),
        "excluded_fraction": float(1.0 - ok.mean()),
        "three_fraction": float((nv == 3).mean()),
        "geometry": geom,
    }


def amplification(pattern: str, strategy: str, theta0_deg: float,
                  convention: str = "sphere", points: int = 20000) -> float:
    """RMS over orientations of sigma(dS) / e for a pattern ending at theta0 (deg)."""
    return amplification_details(pattern, strategy, theta0_deg, convention, points)["factor"]


def figure2_table(ranges: Iterable[float], convention: str = "sphere",
                  points: int = 20000) -> list[dict]:
    """Rows (pattern, range_deg, strategy, factor, excluded_fraction, three_fraction)."""
    rows = []
    for pattern in PATTERNS:
        for strategy in STRATEGIES:
            for th0 in ranges:
                d = amplification_details(pattern, strategy, float(th0), convention, points)
                rows.append({"pattern": pattern, "range_deg": float(th0), "strategy": strategy,
                             "factor": d["factor"], "excluded_fraction": d["excluded_fraction"],
                             "three_fraction": d["three_fraction"], "convention": convention})
    return rows


def cosine_mixed_minimum(convention: str = "sphere", lo: float = 30.0, hi: float = 45.0,
                         points: int = 20000) -> tuple[float, float]:
    """(theta0, factor) at the minimum of the cosine pattern's mixed-strategy curve."""
    res = minimize_scalar(lambda t: amplification("cosine", "mixed", t, convention, points),
                          bounds=(lo, hi), method="bounded", options={"xatol": 0.05})
    return float(res.x), float(res.fun)


def edge_resolution_microinch(goal_arcsec: float, factor: float,
                              radius_inch: float = 1.0) -> float:
    """Edge error e (micro-inch) that gives ``goal_arcsec`` with amplification ``factor``."""
    return goal_arcsec * ARCSEC * radius_inch / factor * 1e6
