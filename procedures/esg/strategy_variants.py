"""The strategy study's variants (report 004, "Pattern Analysis" summary and Figure 3;
docs/esg-options.md): the colatitude pattern type, two sets of pattern lines, four
non-orthogonal pickoffs against three orthogonal, and Figure 3's curves for the cosine
pattern with extended range.

The report states only the conclusions of its 1968 study ("An orthogonal arrangement of
three pickoffs provided more accuracy than a non-orthogonal arrangement of four pickoffs";
"Two sets of pattern lines provided slightly more accuracy than one set") and describes
Figure 3 in words. Our design, on procedures/esg/strategy.py's per-pickoff error and
orientation average:

* colatitude pattern: the line 90 deg - theta = K phi near phi = 0 (colatitude linear in
  longitude), T = |d theta / d phi| = K everywhere; K from the same Figure 1 spacing rule;
* n sets of lines: the per-pickoff variance divided by n and the allotment pi / (2n)
  (``PatternGeometry.n_sets``, already in the study's geometry);
* any pickoff set P (m unit rows): a pickoff views the pattern when |p . s| <= cos(th0);
  with three or more viewing, the spin axis by weighted least squares on the viewing
  cosines, normalised: E|dS|^2 = trace((I - s s') (P' W P)^-1 (I - s s')), W the inverse
  variances (eq. 3 for three orthogonal pickoffs); with two, the pair's two-pickoff mode
  (the unit-length condition for the third component; eq. 2 for orthogonal pickoffs);
  "two_pickoff" always takes the viewing pair of least error (the report's rule for its
  two counters); "mixed" uses every viewing pickoff when three or more view;
* four pickoffs: the normals of a regular tetrahedron's faces (109.47 deg apart), the
  symmetric non-orthogonal arrangement;
* Figure 3 (cosine pattern): the mixed curve; "all three": eq. 3 over the orientations
  where all three view; the minimum and maximum of the mixed strategy's two-pickoff
  readouts (the report: both come from the two-pickoff mode).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq

from procedures.esg.strategy import (
    HALF_LINE_SHARE,
    NORMAL_SPACING_IN,
    PatternGeometry,
    fibonacci_sphere,
    pattern_geometry,
)

VARIANT_PATTERNS = ("great_circle", "cosine", "colatitude")
STRATEGIES = ("two_pickoff", "mixed")


def orthogonal_three() -> np.ndarray:
    """The SDESG's three orthogonal pickoffs."""
    return np.eye(3)


def tetrahedral_four() -> np.ndarray:
    """Four pickoffs along the normals of a regular tetrahedron's faces."""
    return np.array([[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0],
                     [-1.0, -1.0, 1.0]]) / math.sqrt(3.0)


class ColatitudeGeometry(PatternGeometry):
    """The colatitude pattern: 90 deg - theta = K phi, T = K."""

    def slope2(self, alpha: ArrayLike) -> np.ndarray:
        return np.full_like(np.asarray(alpha, dtype=float), self.k * self.k)


def geometry(pattern: str, theta0_deg: float, n_sets: int = 1,
             convention: str = "sphere") -> PatternGeometry:
    """The study's geometry of a pattern ending at theta0 (Figure 1 spacing rule)."""
    if pattern not in VARIANT_PATTERNS:
        raise ValueError(f"pattern must be one of {VARIANT_PATTERNS}, not {pattern!r}")
    if pattern != "colatitude":
        return pattern_geometry(pattern, theta0_deg, convention, n_sets)
    th0 = math.radians(theta0_deg)
    s0 = math.sin(th0)
    allot = math.pi / (2 * n_sets)
    lat0 = math.pi / 2 - th0

    def x_of(k: float) -> tuple[float, float]:
        td = k / s0 if convention == "sphere" else k
        return NORMAL_SPACING_IN * math.sqrt(1.0 + td * td) / td, math.atan(td)

    def resid(ph0: float) -> float:
        return ph0 - (allot - HALF_LINE_SHARE * x_of(lat0 / ph0)[0] / s0)

    ph0 = brentq(resid, 1e-6, allot, xtol=1e-14)
    k = lat0 / ph0
    x, delta = x_of(k)
    return ColatitudeGeometry("colatitude", theta0_deg, convention, n_sets, k=k,
                              phi0_deg=math.degrees(ph0), delta_deg=math.degrees(delta),
                              x_inch=x)


def _variance(geom: PatternGeometry, alpha: np.ndarray) -> np.ndarray:
    base = 1.0 - alpha * alpha if geom.convention == "sphere" else np.ones_like(alpha)
    return (base + geom.slope2(alpha)) / (2.0 * geom.n_sets)


def readout_variances(geom: PatternGeometry, pickoffs: ArrayLike, s: np.ndarray
                      ) -> dict[str, np.ndarray]:
    """Per orientation: E|dS|^2 / e^2 of the best pair ("pair"), of every viewing pickoff
    ("all", NaN with fewer than three), and the number viewing ("n")."""
    p = np.asarray(pickoffs, dtype=float)
    alpha = s @ p.T
    view = np.abs(alpha) <= math.cos(math.radians(geom.theta0_deg))
    var = _variance(geom, alpha)
    n = view.sum(axis=1)
    best = np.full(len(s), np.inf)
    for i, j in itertools.combinations(range(len(p)), 2):
        m = np.stack([np.broadcast_to(p[i], s.shape), np.broadcast_to(p[j], s.shape), s],
                     axis=1)
        ok = view[:, i] & view[:, j] & (np.abs(np.linalg.det(m)) > 1e-9)
        jac = np.zeros((len(s), 3, 3))
        jac[ok] = np.linalg.inv(m[ok])
        v = (jac[:, :, 0] ** 2).sum(1) * var[:, i] + (jac[:, :, 1] ** 2).sum(1) * var[:, j]
        best = np.where(ok, np.minimum(best, v), best)
    w = np.where(view, 1.0 / var, 0.0)
    info = np.einsum("nk,ka,kb->nab", w, p, p)
    three = n >= 3
    cov = np.full((len(s), 3, 3), np.nan)
    cov[three] = np.linalg.inv(info[three])
    proj = np.eye(3)[None] - s[:, :, None] * s[:, None, :]
    full = np.einsum("nab,nbc,nca->n", proj, cov, proj)
    return {"pair": np.where(np.isfinite(best), best, np.nan), "all": full, "n": n}


def amplification(pattern: str, strategy: str, theta0_deg: float, n_sets: int = 1,
                  pickoffs: ArrayLike | None = None, points: int = 20000,
                  convention: str = "sphere") -> dict:
    """RMS amplification over orientations (as Figure 2), with the fraction of
    orientations left unread (fewer than two viewing) and of all-pickoff readouts."""
    if strategy not in STRATEGIES:
        raise ValueError(f"strategy must be one of {STRATEGIES}, not {strategy!r}")
    p = orthogonal_three() if pickoffs is None else np.asarray(pickoffs, dtype=float)
    geom = geometry(pattern, theta0_deg, n_sets, convention)
    r = readout_variances(geom, p, fibonacci_sphere(points))
    v = r["pair"]
    if strategy == "mixed":
        v = np.where(r["n"] >= 3, r["all"], v)
    ok = np.isfinite(v)
    return {"factor": float(math.sqrt(v[ok].mean())), "excluded_fraction": float(1 - ok.mean()),
            "all_fraction": float((r["n"] >= 3).mean())}


def figure3(theta0_deg: float, points: int = 20000, convention: str = "sphere") -> dict:
    """Figure 3's four curves at one range of the cosine pattern: mixed, all three, and the
    minimum and maximum of the mixed strategy's two-pickoff readouts."""
    geom = geometry("cosine", theta0_deg, 1, convention)
    r = readout_variances(geom, orthogonal_three(), fibonacci_sphere(points))
    three = r["n"] == 3
    two = (r["n"] == 2) & np.isfinite(r["pair"])
    mixed = np.where(three, r["all"], r["pair"])
    ok = np.isfinite(mixed)
    sd_two = np.sqrt(r["pair"][two])
    return {"range_deg": float(theta0_deg),
            "mixed": float(math.sqrt(mixed[ok].mean())),
            "all_three": float(math.sqrt(r["all"][three].mean())) if three.any() else None,
            "two_min": float(sd_two.min()) if two.any() else None,
            "two_max": float(sd_two.max()) if two.any() else None,
            "three_fraction": float(three.mean())}


def variants_table(theta0_deg: float = 43.0, points: int = 20000) -> list[dict]:
    """The study's variants at one range: each pattern type with one and two sets of lines,
    and three orthogonal against four tetrahedral pickoffs, both strategies."""
    rows = []
    for pattern in VARIANT_PATTERNS:
        for n_sets in (1, 2):
            for name, p in (("three orthogonal", orthogonal_three()),
                            ("four tetrahedral", tetrahedral_four())):
                for strategy in STRATEGIES:
                    a = amplification(pattern, strategy, theta0_deg, n_sets, p, points)
                    rows.append({"pattern": pattern, "sets": n_sets, "pickoffs": name,
                                 "strategy": strategy, "range_deg": theta0_deg, **a})
    return rows
