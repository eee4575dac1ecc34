"""Quantization of a count at a gate's two edges when the edges' phases are correlated.

A pulse train read at the last sampling instant before each edge of a gate of length T
loses the time back to that instant at each edge. The offsets at the two edges differ by
c = frac(T f_s) sampling periods (f_s the sampling rate), so the count's error from the
sampling is rho tau (c - [v + c >= 1]) with v the start's offset (uniform): variance
(rho tau)^2 c (1 - c), not the (rho tau)^2 / 6 of two independent edges. 1/6 is the average
of c (1 - c) over c uniform; how well c is known sets which applies (``fraction_variance``).
"""

from __future__ import annotations

import math

import numpy as np

UNIFORM = 1.0 / 6.0  # E[x (1 - x)] for x uniform on [0, 1)
_MAX_TERMS = 20000


def fraction_variance(c0: float, sigma: float) -> float:
    """E[x (1 - x)] for x = frac(c0 + sigma xi), xi standard normal: the Fourier series
    x (1 - x) = 1/6 - sum_k cos(2 pi k x) / (pi k)^2, each term damped by the Gaussian's
    characteristic function exp(-2 (pi k sigma)^2). sigma = 0: c0 (1 - c0); large: 1/6."""
    f = c0 - math.floor(c0)
    if sigma <= 0.0:
        return f * (1.0 - f)
    kmax = min(_MAX_TERMS, int(math.ceil(math.sqrt(40.0) / (math.pi * sigma * math.sqrt(2.0)))))
    if kmax < 1:
        return UNIFORM
    k = np.arange(1, kmax + 1, dtype=float)
    damping = np.exp(-2.0 * (math.pi * k * sigma) ** 2)
    terms = np.cos(2 * math.pi * k * f) * damping / (math.pi * k) ** 2
    return float(UNIFORM - terms.sum())


def edge_sampling_var(gate_s: float, n1: float, sample_rate_hz: float, clock_ppm: float | None,
                      clock_quantization_var: float) -> float:
    """E[c (1 - c)] of a clock-counted gate (sampling periods^2 per (rho tau)^2).

    ``clock_ppm`` None: the sampling clock is not known against the counter clock, c is
    uniform (1/6, the two edges independent). Otherwise c = frac(T f_s) with T = n1 S1 read
    from the counter, uncertain by the clock's quantization (``clock_quantization_var``
    ticks^2) and the sampling rate's relative error (ppm) over the gate."""
    if clock_ppm is None:
        return UNIFORM
    periods = gate_s * sample_rate_hz
    tick = gate_s / n1 * sample_rate_hz if n1 > 0 else 0.0  # one clock tick, in periods
    sigma = math.hypot(periods * clock_ppm * 1e-6, tick * math.sqrt(clock_quantization_var))
    return fraction_variance(periods, sigma)
