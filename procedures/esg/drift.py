"""Spin-axis drift correction by linear interpolation in time (report 004, step 13).

Every calibration scan starts and ends at the same spindle setting near the equator (the
baseline). Between the two baseline readings the spin axis drifts; at the baseline the
count ratio changes by k * delta, k = d(CR)/d(gamma) the local slope of count ratio
against spindle angle measured by the 10-minute scan of step 9 (the spindle moves the
pickoff one-to-one in colatitude there). The drift is expressed as an equivalent
spindle angle delta(t): a sample taken at spindle reading gamma and time t reads what the
pickoff would have read at gamma + delta(t) at the scan's start, so the corrected angle
is gamma + delta(t), with

    delta(t) = (CR1 - CR0) / k * (t - t0) / (t1 - t0)         (linear in time).

Predicted 1-sigma of the correction at time t (f = (t - t0)/(t1 - t0), T = t1 - t0,
tau = t - t0), three independent parts:

* baseline scatter: the baseline count ratios are means of n0 and n1 data lines with a
  line-to-line scatter s (given, or pooled from the baseline lines themselves with
  n0 + n1 - 2 degrees of freedom): var = f^2 s^2 (1/n0 + 1/n1) / k^2;
* slope uncertainty (optional, from ``fit_slope``): var = (f (CR1 - CR0) sigma_k / k^2)^2;
* drift-rate variation: interpolation is exact for a constant rate. If the rate changes
  linearly by Dr over the scan (a quadratic drift), the interpolation error is
  Dr tau (T - tau) / (2 T), largest (Dr T / 8) at mid-scan. The user gives a bound B on
  |Dr| (degrees per time unit); treating Dr as uniform in [-B, B] its 1-sigma is
  B / sqrt(3), so var = (B / sqrt 3 * tau (T - tau) / (2 T))^2. B = 0 trusts the
  constant-rate assumption. (The report names electric torque, which depends on the
  spin-axis orientation in the case, and rundown as the causes of a changing rate.)

Times may be in any unit (the processor's hours, say) as long as B uses the same one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["SlopeFit", "fit_slope", "DriftCorrection", "drift_correction"]


@dataclass(frozen=True)
class SlopeFit:
    """Straight-line fit CR = intercept + slope (gamma - gamma_ref) [+ q (t - t_ref)]."""

    slope: float            # count ratio per spindle degree
    intercept: float        # count ratio at gamma_ref (and t_ref)
    gamma_ref: float
    sigma_slope: float
    rms: float              # residual rms (count ratio)
    drift_rate_deg: float   # equivalent spindle-angle drift per time unit (0 without times)

    def angle(self, cr: ArrayLike) -> np.ndarray:
        """Spindle angle (deg) at which the line reaches the count ratio(s), at t_ref."""
        return self.gamma_ref + (np.asarray(cr, dtype=float) - self.intercept) / self.slope


def fit_slope(spindle_deg: ArrayLike, cr: ArrayLike, times: ArrayLike | None = None) -> SlopeFit:
    """Local slope d(CR)/d(gamma) from the step-9 scan (deg of spindle angle).

    With ``times`` the model carries a linear drift term q (t - t_ref): the scan starts and
    ends at the same setting, so a drift constant in rate separates from the slope and is
    returned as the equivalent angle rate q / k.
    """
    g = np.asarray(spindle_deg, dtype=float)
    y = np.asarray(cr, dtype=float)
    g0 = float(g.mean())
    cols = [np.ones_like(g), g - g0]
    if times is not None:
        t = np.asarray(times, dtype=float)
        cols.append(t - t.mean())
    a = np.stack(cols, axis=1)
    if len(y) <= a.shape[1]:
        raise ValueError("not enough scan points for the line fit")
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    res = y - a @ coef
    dof = len(y) - a.shape[1]
    s2 = float(res @ res) / dof
    cov = s2 * np.linalg.inv(a.T @ a)
    rate = float(coef[2] / coef[1]) if times is not None else 0.0
    return SlopeFit(slope=float(coef[1]), intercept=float(coef[0]), gamma_ref=g0,
                    sigma_slope=math.sqrt(cov[1, 1]), rms=math.sqrt(float(res @ res) / len(y)),
                    drift_rate_deg=rate)


@dataclass(frozen=True)
class DriftCorrection:
    """Linear-in-time drift correction of one scan; see the module docstring."""

    t0: float
    t1: float
    cr0: float
    cr1: float
    slope: float
    sigma_cr0: float        # 1-sigma of the start baseline count ratio (mean of its lines)
    sigma_cr1: float
    sigma_slope: float = 0.0
    rate_change_bound: float = 0.0

    @property
    def total_deg(self) -> float:
        """Drift over the whole scan, equivalent spindle degrees."""
        return (self.cr1 - self.cr0) / self.slope

    def _f(self, t: ArrayLike) -> np.ndarray:
        return (np.asarray(t, dtype=float) - self.t0) / (self.t1 - self.t0)

    def angle(self, t: ArrayLike) -> np.ndarray:
        """Drift angle delta(t) (deg) to add to the spindle reading."""
        return self._f(t) * self.total_deg

    def corrected(self, spindle_deg: ArrayLike, t: ArrayLike) -> np.ndarray:
        return np.asarray(spindle_deg, dtype=float) + self.angle(t)

    def sigma(self, t: ArrayLike) -> np.ndarray:
        """Predicted 1-sigma (deg) of the correction at time(s) t."""
        f = self._f(t)
        k = self.slope
        var = f * f * (self.sigma_cr0 ** 2 + self.sigma_cr1 ** 2) / (k * k)
        var = var + (f * self.total_deg * self.sigma_slope / k) ** 2
        span = self.t1 - self.t0
        tau = np.asarray(t, dtype=float) - self.t0
        q = self.rate_change_bound / math.sqrt(3.0) * tau * (span - tau) / (2.0 * span)
        return np.sqrt(var + q * q)


def _baseline(cr: ArrayLike, t: ArrayLike) -> tuple[float, float, int, float]:
    cr = np.atleast_1d(np.asarray(cr, dtype=float))
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if t.size == 1 and cr.size > 1:
        t = np.full(cr.shape, float(t[0]))
    if t.shape != cr.shape:
        raise ValueError("baseline readings and their times must have the same shape")
    return float(cr.mean()), float(t.mean()), cr.size, float(((cr - cr.mean()) ** 2).sum())


def drift_correction(start_cr: ArrayLike, start_t: ArrayLike, end_cr: ArrayLike,
                     end_t: ArrayLike, slope: float, *,
                     line_sigma: float | None = None, sigma_slope: float = 0.0,
                     rate_change_bound: float = 0.0) -> DriftCorrection:
    """The correction from the baseline readings at the start and end of a scan.

    ``start_cr``/``end_cr`` are the baseline data lines' count ratios (scalar or array),
    ``start_t``/``end_t`` their times (scalar or array, same unit as ``rate_change_bound``
    per unit). ``line_sigma`` is the count-ratio scatter of one line; if None it is pooled
    from the baseline lines (needs at least three lines in all).
    """
    cr0, t0, n0, ss0 = _baseline(start_cr, start_t)
    cr1, t1, n1, ss1 = _baseline(end_cr, end_t)
    if t1 <= t0:
        raise ValueError("the end baseline must come after the start baseline")
    if slope == 0.0:
        raise ValueError("zero count-ratio slope")
    if line_sigma is None:
        dof = n0 + n1 - 2
        if dof < 1:
            raise ValueError("give line_sigma: single baseline readings carry no scatter")
        line_sigma = math.sqrt((ss0 + ss1) / dof)
    return DriftCorrection(t0=t0, t1=t1, cr0=cr0, cr1=cr1, slope=float(slope),
                           sigma_cr0=line_sigma / math.sqrt(n0),
                           sigma_cr1=line_sigma / math.sqrt(n1),
                           sigma_slope=float(sigma_slope),
                           rate_change_bound=float(rate_change_bound))
