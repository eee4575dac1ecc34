"""The gyro counts' standard errors the calibration's computations weight with (Chart
II-7/II-7Q speed series, the J gates): quantization, angle random walk, drift and the pier's
tilt over a gate. Apart from the computations so that the plot child (laboratory.isu.plots)
weights the nonlinearity plot's fit alike without importing the day's procedures."""

from __future__ import annotations

import functools
import math

import numpy as np

from procedures.isu.calibration.noise_spec import NoiseSpec


def count_sigma(noise: NoiseSpec, gate_s: float, dphi_arcsec: float) -> float:
    """One gyro count's standard error (pulses) over a gate: quantization, ARW, drift."""
    arw = noise.gyro_arw_deg_rt_hr * 3600.0 / 60.0 * math.sqrt(gate_s)  # arcsec
    drift = noise.gyro_drift_sigma_deg_hr * gate_s  # arcsec (deg/hr = arcsec/s)
    return math.sqrt(noise.count_quantization_var + (arw**2 + drift**2) / dphi_arcsec**2)


BISECTOR_ALONG = 1.0 / math.sqrt(2.0)  # G . r with the II-7Q rotary axis r = (G + S)/sqrt2


def tilt_change_about_north_arcsec(noise: NoiseSpec, gate_s: float) -> float:
    """Pier-tilt change over a gate about the north-south axis (the rotary axis R1 at
    phi1 = 90, Chart I-4), arcsec: var = 2 (nn(0) - nn(T)) of the tilt covariance."""
    _, nn0, _ = noise.tilt_covariance(0.0)
    _, nn1, _ = noise.tilt_covariance(gate_s)
    return math.sqrt(max(2.0 * float(nn0 - nn1), 0.0)) * 180.0 / math.pi * 3600.0


# a day asks for the same gate and rate of the II-7Q series once per gyro: 18 times, 7
# different, 1.5 ms each (issue 17); NoiseSpec is frozen, so it keys the cache by content
@functools.lru_cache(maxsize=64)
def tilt_seen_turning_arcsec(noise: NoiseSpec, gate_s: float, rate_deg_s: float,
                              steps: int = 240) -> float:
    """Pier tilt about the east axis seen over a gate by a unit axis that turns with the
    table about R1 (north-south) at ``rate_deg_s``, arcsec: the angle int eps_E' cos(w t +
    phi) dt, phi uniform; near the wobble's period (60 s against 72 s a turn at 5 deg/s) it
    does not average out over whole turns. Held by its arguments' values (a pure function
    of them)."""
    t = np.linspace(0.0, gate_s, steps + 1)
    # ee at |t_i - t_j| is symmetric bit for bit (x - y = -(y - x) in floating point): the
    # upper triangle is evaluated once and mirrored (half the cosines, exps and sincs)
    upper = np.triu_indices(t.size)
    ee_upper, _, _ = noise.tilt_covariance(np.subtract.outer(t, t)[upper])
    ee = np.empty((t.size, t.size))
    ee[upper] = ee_upper
    ee.T[upper] = ee_upper
    cov = np.diff(np.diff(ee, axis=0), axis=1)  # of the tilt changes over the steps
    w = math.radians(rate_deg_s) * 0.5 * (t[1:] + t[:-1])
    c, s = np.cos(w), np.sin(w)
    var = 0.5 * float(c @ cov @ c + s @ cov @ s)
    return math.sqrt(max(var, 0.0)) * 180.0 / math.pi * 3600.0


def speed_count_sigma(noise: NoiseSpec, gate_s: float, p_dot: float, dphi_arcsec: float,
                      along: float = 1.0, across: float = 0.0, rate_deg_s: float = 0.0
                      ) -> float:
    """One speed's gyro count standard error (pulses) in a Chart II-7 or II-7Q series: as
    ``count_sigma``, with the quantization at the pulse rate ``p_dot`` (pulses exist only
    at the rebalance loop's sampling instants: q (1 + (P' / f_s)^2)) and the pier's tilt
    over the gate, which the rotary pulses do not count: its change about the rotary axis,
    seen through ``along`` (G . r: 1 for II-7, 1/sqrt2 for II-7Q), and its east component,
    seen through the turning part ``across`` of G (0 for II-7, 1/sqrt2 for II-7Q). None
    scales with the gyro noise (issue 19: Q_II at -4.7 sigma at 0.38x gyro noise)."""
    quant = noise.count_quantization_var * (p_dot / noise.gyro_sample_rate_hz) ** 2
    tilt = along * tilt_change_about_north_arcsec(noise, gate_s) / dphi_arcsec
    var = count_sigma(noise, gate_s, dphi_arcsec) ** 2 + quant + tilt**2
    if across:
        var += (across * tilt_seen_turning_arcsec(noise, gate_s, rate_deg_s)
                / dphi_arcsec) ** 2
    return math.sqrt(var)


def series_sigmas(noise: NoiseSpec, pts: list[dict], dphi_arcsec: float,
                   along: float = 1.0, across: float = 0.0) -> np.ndarray:
    """``speed_count_sigma`` of each speed of a series."""
    return np.array([speed_count_sigma(noise, abs(p["counts"] / p["p_dot"]), abs(p["p_dot"]),
                                       dphi_arcsec, along, across, p["rate_deg_s"])
                     for p in pts])


def tilt_change_sigma_arcsec(noise: NoiseSpec, gate_s: float) -> float:
    """Pier-tilt change over a gate about a horizontal axis of random azimuth, arcsec.

    A gyro whose input axis is horizontal sees it as an angle (wobble: about 1.2 arcsec in
    20 s); var = (ee(0) - ee(T)) + (nn(0) - nn(T)) from the tilt covariance.
    """
    ee0, nn0, _ = noise.tilt_covariance(0.0)
    ee1, nn1, _ = noise.tilt_covariance(gate_s)
    var = float(ee0 - ee1 + nn0 - nn1)
    return math.sqrt(max(var, 0.0)) * 180.0 / math.pi * 3600.0
