"""Pattern calibration from the acquisition (report 004, step 13 and Appendix B).

Each scan point gets the colatitude the laboratory assigns it (the equator's count ratio
is 90 deg, the dividing head adds its angle, the baseline readings before and after the
scan correct the drift linearly in time) and a predicted 1-sigma of that assignment. The
nominal mechanization comes from the two equal-ratio points; the 7th-order weighted
Chebyshev fit of the deviation is made on the points of a schedule, and the rest are
read out with it (Tables B-1..B-4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from procedures.esg.acquisition import Acquisition, EsgPlan, Scan, fine_slope, plan_slope_per_deg
from procedures.esg.chebyshev_fit import ChebyshevFit, fit_deviation
from procedures.esg.mechanization import (
    Mechanization,
    equal_ratio_colatitude,
    fit_mechanization,
    pickoff_gram,
)

HEAD_SIGMA_ARCSEC = 1.0  # dividing head: "two seconds or less" taken as 2 sigma

# which scans and spindle offsets each schedule fits (report, Readout Test Results)
SCHEDULES = ("5deg", "1-2-5deg")


@dataclass
class Point:
    scan: str
    increment_deg: float
    offset_deg: float  # from the equator, positive towards the first hemisphere
    t_s: float  # mean processor time of the lines, s
    times_s: list[float]
    cr: float
    colatitude_deg: float  # as the laboratory assigns it
    sigma_arcsec: float  # predicted 1-sigma of that assignment


def in_schedule(p: Point, schedule: str) -> bool:
    """Whether a point enters the fit of a schedule (the equator scan never does)."""
    if p.scan.startswith("9"):
        return False
    off = abs(p.offset_deg)
    if schedule == "5deg":
        return p.increment_deg == 5.0 or p.offset_deg == 0.0
    if schedule == "1-2-5deg":
        if p.increment_deg == 5.0 or p.offset_deg == 0.0:
            return off <= 35.0 + 1e-9
        if p.increment_deg == 2.0:
            return 35.0 < off <= 39.0 + 1e-9
        return off > 39.0
    raise ValueError(f"unknown schedule {schedule!r}: {', '.join(SCHEDULES)}")


def _line_sigma(acq: Acquisition) -> float:
    """Pooled line-to-line count-ratio scatter of pickoff 2 over every setting."""
    ss, dof = 0.0, 0
    for sc in acq.scans:
        sets = [sc.baseline.start, sc.baseline.end] + [p.setting for p in sc.points]
        for s in sets:
            v = np.asarray(s.line_cr.get(2, []), dtype=float)
            if v.size > 1:
                ss += float(((v - v.mean()) ** 2).sum())
                dof += v.size - 1
    return math.sqrt(ss / dof) if dof else 0.0


@dataclass(frozen=True)
class Budget:
    """What the predicted assignment error is made of (deg unless named)."""

    slope_per_deg: float  # d(CR)/d(colatitude) at the equator, from step 9
    line_sigma: float  # count ratio, one line
    equator_deg: float  # the equator's count ratio (steps 4, 6, 7)
    head_deg: float
    drift_bound_deg_s: float  # change of drift rate allowed over a scan
    # d(CR)/d(colatitude) on the equator's own track (step 7; step 9's without it) and
    # the 1-sigma of that measurement, per degree
    slope_eq_per_deg: float = 0.0
    slope_eq_sigma: float = 0.0


def budget(acq: Acquisition, plan: EsgPlan, n_lines: int = 5) -> Budget:
    """The error sources of the colatitude assignment, from the data and the lab's specs.

    The count-ratio noise at a track is carried into colatitude through that track's own
    measured slope (steps 6 and 7): on a rough pattern it can be a fraction of the
    drawing's or of step 9's two-degree fit, and the noise then moves the track more."""
    sc9 = next(s for s in acq.scans if s.name == "9")
    k = -fine_slope(sc9)  # per degree of colatitude
    s_line = _line_sigma(acq)
    s_set = s_line / math.sqrt(n_lines)
    k_design = abs(plan_slope_per_deg(acq.theta_star_deg, plan))
    k_a = abs(acq.slope_a_per_deg) or k_design
    k_b = abs(acq.slope_b_per_deg) or k_design
    # signed like k (colatitude_sign turns it from per degree of spindle); a journal
    # recorded before step 7 read it (0.0) keeps step 9's
    k_eq = acq.colatitude_sign * acq.slope_eq_per_deg or k
    head = HEAD_SIGMA_ARCSEC / 3600.0
    s_cr_ab = s_set * math.sqrt(2.5) / 3.0  # mean of three pickoffs, pickoff 2 read twice
    var_ga = s_set ** 2 / (2 * k_a ** 2) + (s_cr_ab / k_a) ** 2 + head ** 2
    var_gb = s_set ** 2 / k_b ** 2 + (s_cr_ab / k_b) ** 2 + head ** 2
    bound = plan.electric_drift_spec_deg_hr / 3600.0
    # step 7 aims at the equator where the drift about the spindle has taken it: that
    # drift is step 6's two readings of the first ratio over their span, carried over the
    # lever (their noise, a setting's each; the head's scale error and the ratio's own
    # error are common to both and cancel)
    var_rate = 2.0 * s_set ** 2 / k_a ** 2 * acq.equator_rate_lever ** 2
    eq = math.sqrt((s_set / k_eq) ** 2 + 0.25 * (var_ga + var_gb) + var_rate)
    # step 7's two readings 2 * step apart, each a setting's mean
    k_sigma = s_set * math.sqrt(2.0) / (2.0 * plan.local_slope_step_deg)
    return Budget(k, s_line, eq, head, bound, k_eq,
                  k_sigma if acq.slope_eq_per_deg else 0.0)


def assign(acq: Acquisition, plan: EsgPlan, n_lines: int = 5) -> tuple[list[Point], Budget]:
    """Colatitude and predicted sigma of every scan point (docs/esg.md, error budget)."""
    bud = budget(acq, plan, n_lines)
    k = bud.slope_eq_per_deg  # d(CR)/d(theta) on the equator's track
    cs = acq.colatitude_sign
    pts: list[Point] = []
    for sc in acq.scans:
        pts.extend(_scan_points(sc, acq, bud, k, cs, n_lines))
    return pts, bud


def _scan_points(sc: Scan, acq: Acquisition, bud: Budget, k: float, cs: int,
                 n_lines: int) -> list[Point]:
    b = sc.baseline
    t0, t1 = b.start.t_s, b.end.t_s
    cr0, cr1 = b.start.ratio(2), b.end.ratio(2)
    theta0 = 90.0 + (cr0 - acq.cr_eq) / k  # pickoff 2 at the baseline, scan start
    drift = (cr1 - cr0) / k  # colatitude change at the baseline over the scan
    s0 = bud.line_sigma / math.sqrt(len(b.start.times_s) or n_lines)
    s1 = bud.line_sigma / math.sqrt(len(b.end.times_s) or n_lines)
    span = t1 - t0
    out = []
    rows = [(0.0, b.gamma_deg, b.start)] + [(p.offset_deg, p.gamma_deg, p.setting)
                                             for p in sc.points]
    for off, gamma, s in rows:
        f = (s.t_s - t0) / span
        theta = theta0 + drift * f + cs * (gamma - b.gamma_deg)
        tau = s.t_s - t0
        nl = bud.drift_bound_deg_s / math.sqrt(3.0) * tau * (span - tau) / (2.0 * span)
        var = ((1 - f) * s0 / k) ** 2 + (f * s1 / k) ** 2 + bud.equator_deg ** 2 + nl ** 2
        # the count-ratio differences carried through the measured slope, and its error
        var += ((theta0 - 90.0 + drift * f) * bud.slope_eq_sigma / k) ** 2
        if off != 0.0:
            var += 2.0 * bud.head_deg ** 2
        out.append(Point(sc.name, sc.increment_deg, off, s.t_s, list(s.times_s), s.ratio(2),
                         theta, math.sqrt(var) * 3600.0))
    return out


def nominal(acq: Acquisition, plan: EsgPlan) -> Mechanization:
    """b, c, dbar (a cosine pattern: K, d0) from the two equal-ratio points (colatitude
    from the mirror angle)."""
    theta_star = equal_ratio_colatitude(pickoff_gram(plan.mirror_angle_deg))
    return fit_mechanization(plan.pattern_kind, acq.cr_a, acq.cr_b, theta_star)


@dataclass
class ScheduleResult:
    name: str
    fit: ChebyshevFit
    calibration: list[dict]
    readout: list[dict]

    @staticmethod
    def rms(rows: list[dict], key: str) -> float:
        v = [r[key] for r in rows if r.get(key) is not None]
        return math.sqrt(sum(x * x for x in v) / len(v)) if v else float("nan")


def calibrate(points: list[Point], params: Mechanization, schedule: str,
              order: int = 7) -> ScheduleResult:
    """Fit a schedule's points; calibration errors on them, readout errors on the rest."""
    fit_pts = [p for p in points if in_schedule(p, schedule)]
    other = [p for p in points if not in_schedule(p, schedule)]
    fit = fit_deviation(np.array([p.cr for p in fit_pts]),
                        np.array([p.colatitude_deg for p in fit_pts]), params, order=order)

    def rows(pts: list[Point]) -> list[dict]:
        out: list[dict] = []
        if not pts:
            return out
        comp = fit.colatitude(np.array([p.cr for p in pts]))
        for p, c in zip(pts, comp, strict=True):
            out.append({"scan": p.scan, "increment_deg": p.increment_deg,
                        "offset_deg": p.offset_deg, "t_s": p.t_s,
                        "colatitude_deg": p.colatitude_deg, "count_ratio": p.cr,
                        "compensated_deg": float(c),
                        "error_arcsec": (float(c) - p.colatitude_deg) * 3600.0,
                        "sigma_assign_arcsec": p.sigma_arcsec})
        return out

    # readout points outside the fitted count-ratio range would be extrapolations
    inside = [p for p in other if fit.lo <= p.cr <= fit.hi]
    return ScheduleResult(schedule, fit, rows(fit_pts), rows(inside))
