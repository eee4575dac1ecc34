"""Predicted errors of an alignment, from the procedures' own error model only.

An alignment's error is the small rotation phi (earth axes U, E, N; ``align_math``) between
its T and the true attitude at the time it refers to. Its predicted covariance is a sum of
independent parts, each mapped to phi by a numerical Jacobian of the alignment computation:

* calibration: each constant of the Calibration Results Sheet the preprocessing uses, moved
  by its predicted sigma, through preprocessing, estimation and the alignment matrix; the
  moves combine with the sheet's correlation of the constants (``correlated_cov``: the
  closed forms share readings, so D0 and A.B of a horizontal accelerometer correlate at
  about -0.65 and -0.4; taken as independent, the level axes came out 1.3-1.9x
  pessimistic); a sheet without a correlation gives independent constants;
* the estimator: the error covariance of g_hat against g at t* (``estimation``), for the
  posterior mean (A^-1) and for the simple average alike, under the lab's NoiseSpec: the
  accelerometer white noise, the IEU's string-count quantization (below), floor vibration,
  and the pier's tilt between the record and t* (Chart I-9's three noise processes);
* the gyros (gyrocompass): angle random walk, pulse quantization and the Gauss-Markov
  random drift averaged over the record, and the pier's tilt rate over it;
* autocollimator readings: noise / sqrt(readings) on each angle, and the pier's tilt between
  the readings and their mean time (mirror alignment).

String-count quantization. The IEU counts whole string cycles, so each interval's
f2 - f1 count is off by e_j - e_(j-1), e being the fractional phases of the two strings at
the interval's ends (variance ``NoiseSpec.count_quantization_var``, counts^2, per end). Over
a record the errors telescope, but an interval of 2 s carries about 0.6 count, 150 micro-g:
far above the white noise (7 micro-g), so an estimator that weights intervals unequally must
know of it. It enters Chart I-9's accelerometer noise phi_n as the covariance function of
the derivative of a narrow stationary process (``quantization_table``), whose interval
integrals have exactly that covariance: 2v on the diagonal, -v next to it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import TypeVar

import numpy as np
from numpy.typing import ArrayLike

from procedures.isu.alignment import estimation as es
from procedures.isu.alignment.align_math import ARCSEC, rotation_error
from procedures.isu.alignment.preprocess import Constants
from procedures.isu.calibration.noise_spec import NoiseSpec

RAD_S_TO_DEG_HR = 180.0 / math.pi * 3600.0
# The floor vibration's covariance (2-30 Hz) tabulated to 5 s at 10 points per 30 Hz cycle:
# M and A^-1 of the default experiments change by under 0.3 % against the table over the
# whole record at 20 points per cycle, and the tape (with its sheet) stays near 100 kB
# instead of 10 MB.
VIBRATION_TABLE: es.TableOptions = {"vibration_max_lag_s": 5.0, "vibration_points_per_cycle": 10}


# ----------------------------------------------------------------------------- noise models
def quantization_table(v: float, dt: float, white: float = 0.0,
                       width_frac: float = 0.05, points: int = 20) -> es.CovarianceTable:
    """phi_n with a white part ``white`` and the quantization of interval integrals.

    The ends' error process e has covariance v exp(-tau^2 / 2 w^2) (w = width_frac dt); its
    derivative's covariance -phi_e'' = v/w^2 (1 - x^2) exp(-x^2/2), x = tau/w, gives interval
    integrals with covariance 2 phi_e(m dt) - phi_e((m+1) dt) - phi_e((m-1) dt): 2v, -v, 0...
    """
    w = width_frac * dt
    h = w / points
    lags = np.arange(int(math.ceil(8 * w / h)) + 1) * h
    x = lags / w
    vals = v / (w * w) * (1.0 - x * x) * np.exp(-0.5 * x * x)
    return es.CovarianceTable(lags_s=tuple(lags.tolist()), values=tuple(vals.tolist()),
                              white=white, zero_beyond=True)


def level_params(
    noise: NoiseSpec,
    dt: float,
    K: int,
    *,
    t1: ArrayLike,
    g_tilde_g: float,
    sigma_g_g: float,
    sigma_theta_arcsec: float,
    eps_t: float,
    d1_pps_per_g: float,
) -> es.LevelParams:
    """Chart I-8 inputs for an experiment (SI, as ``estimation``), phi_n with quantization.

    ``d1_pps_per_g``: the accelerometers' scale factor, which turns the count quantization
    into m/s^2 s; rounded to three figures, so that a tape made with one calibration still
    matches the experiment after the next (the quantization needs no more).
    """
    p = es.level_params_from_noise_spec(
        noise, dt, K, g_tilde=g_tilde_g * es.G0, sigma_g=sigma_g_g * es.G0, T1=t1,
        sigma_theta=sigma_theta_arcsec * ARCSEC, eps_t=eps_t, **VIBRATION_TABLE,
    )
    q = (noise.accel_white_micro_g_rt_hz * es.MICRO_G) ** 2
    d1 = float(f"{d1_pps_per_g:.3g}")
    v = noise.count_quantization_var * (es.G0 / d1) ** 2
    return p.model_copy(update={"phi_n": quantization_table(v, dt, q)})


def tilt_motion_cov(noise: NoiseSpec, times: ArrayLike, t_ref: float) -> np.ndarray:
    """Covariance (E, N; rad^2) of mean_i tilt(t_i) - tilt(t_ref)."""
    t = np.asarray(times, dtype=float)
    lag = t[:, None] - t[None, :]
    ee, nn, en = (np.asarray(x) for x in noise.tilt_covariance(lag))
    re, rn, rx = (np.asarray(x) for x in noise.tilt_covariance(t - t_ref))
    z = [np.asarray(x) for x in noise.tilt_covariance(0.0)]
    out = np.empty((2, 2))
    for (i, j), full, ref, zero in (((0, 0), ee, re, z[0]), ((1, 1), nn, rn, z[1]),
                                    ((0, 1), en, rx, z[2])):
        out[i, j] = float(full.mean() - 2.0 * ref.mean() + zero)
    out[1, 0] = out[0, 1]
    return out


def tilt_rate_cov(noise: NoiseSpec, span_s: float) -> np.ndarray:
    """Covariance (E, N; (deg/hr)^2) of the mean tilt rate over a record of ``span_s``."""
    z = [float(x) for x in noise.tilt_covariance(0.0)]
    s = [float(x) for x in noise.tilt_covariance(span_s)]
    c = np.array([[z[0] - s[0], z[2] - s[2]], [z[2] - s[2], z[1] - s[1]]]) * 2.0
    return c / span_s**2 * RAD_S_TO_DEG_HR**2


def gyro_rate_variance(noise: NoiseSpec, span_s: float, dphi_arcsec: float) -> dict:
    """Variance ((deg/hr)^2) of one gyro's mean rate over ``span_s`` by source."""
    arw = noise.gyro_arw_deg_rt_hr**2 / (span_s / 3600.0)
    quant = noise.count_quantization_var * dphi_arcsec**2 / span_s**2  # arcsec/s = deg/hr
    r = span_s / noise.gyro_drift_tau_s
    f = 2.0 / (r * r) * (r - 1.0 + math.exp(-r)) if r > 1e-6 else 1.0
    drift = noise.gyro_drift_sigma_deg_hr**2 * f
    return {"arw": arw, "quantization": quant, "drift": drift}


# ----------------------------------------------------------------------------- Jacobians
def jacobian(f: Callable[[np.ndarray], np.ndarray], x0: ArrayLike, steps: ArrayLike
             ) -> np.ndarray:
    """Central-difference Jacobian of f at x0 (columns per input)."""
    x0 = np.asarray(x0, dtype=float)
    cols = []
    for i, h in enumerate(np.broadcast_to(np.asarray(steps, dtype=float), x0.shape)):
        e = np.zeros_like(x0)
        e[i] = h
        cols.append((np.asarray(f(x0 + e)) - np.asarray(f(x0 - e))) / (2.0 * h))
    return np.column_stack(cols)


def phi_of(t_ref: np.ndarray, make_t: Callable[[np.ndarray], np.ndarray]
           ) -> Callable[[np.ndarray], np.ndarray]:
    """x -> rotation error (U, E, N; rad) of make_t(x) against t_ref."""
    return lambda x: rotation_error(make_t(x), t_ref)


R = TypeVar("R")


def memoized(solve: Callable[[Constants], R]) -> Callable[[Constants], R]:
    """``solve`` computed once per set of constant values: an error model's perturbation
    passes (T, then scalars such as |g|) move the same constants by the same sigmas."""
    memo: dict[tuple[float, ...], R] = {}

    def once(cc: Constants) -> R:
        key = tuple(cc.values.values())
        if key not in memo:
            memo[key] = solve(cc)
        return memo[key]

    return once


def calibration_terms(constants: Constants, solve: Callable[[Constants], np.ndarray],
                      keys: Iterable[tuple[str, str]]) -> dict[tuple[str, str], np.ndarray]:
    """phi change (rad) when each constant in ``keys`` moves by its sigma.

    ``solve(constants) -> T``. Central differences, one constant at a time.
    """
    t0 = solve(constants)
    out = {}
    for k in keys:
        s = constants.sigmas.get(k, 0.0)
        if not s:
            continue
        plus = rotation_error(solve(constants.perturbed(k, s)), t0)
        minus = rotation_error(solve(constants.perturbed(k, -s)), t0)
        out[k] = 0.5 * (plus - minus)
    return out


def cov_of(terms: Iterable[np.ndarray]) -> np.ndarray:
    """Covariance of independent contributions (sum of outer products)."""
    c = np.zeros((3, 3))
    for v in terms:
        c += np.outer(v, v)
    return c


def correlated_cov(terms: dict[tuple[str, str], np.ndarray], constants: Constants,
                   keep: Callable[[tuple[str, str]], bool] = lambda k: True) -> np.ndarray:
    """Covariance sum_ij rho_ij v_i v_j^T of the terms (each a one-sigma move) ``keep``
    selects, with the constants' correlation rho (``Constants.rho``)."""
    keys = [k for k in terms if keep(k)]
    if not keys:
        return np.zeros((3, 3))
    v = np.array([terms[k] for k in keys])  # n x 3
    rho = constants.rho_matrix(keys)
    c = v.T @ rho @ v
    return 0.5 * (c + c.T)


def as_enu_arcsec(cov: np.ndarray) -> list[float]:
    """[about east, about north, about up] 1-sigma of a phi covariance (U, E, N), arcsec."""
    d = np.sqrt(np.maximum(np.diag(cov), 0.0)) / ARCSEC
    return [float(d[1]), float(d[2]), float(d[0])]
