"""The Gauss-Markov noise stays finite and statistically right for every time constant a
configuration can give it, against the knot step too (sim/noise.py).

Tolerances come from the sample count: for an AR(1) sequence of N knots with coefficient
phi, the sample variance has relative standard deviation sqrt(2 (1 + phi^2) / ((1 - phi^2) N))
and the lag-1 autocorrelation a standard deviation sqrt((1 - phi^2) / N) (Bartlett). Each
check allows 5 of those standard deviations; the seeds are fixed, so a pass is repeatable.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.noise import _ar1, gauss_markov
from station.config.isu import ConfigError, default_dict, load_config

N = 300_000  # knots per process
K = 5.0  # standard deviations allowed


def knots(h: float, sigma: float, tau: float, seed: int) -> np.ndarray:
    p = gauss_markov(h, sigma, tau, seed, "test", "gm")
    return np.asarray(p.value(np.arange(N) * h))


@pytest.mark.parametrize("tau_over_h", [0.2, 0.35, 1.0, 3.0, 10.0, 100.0])
def test_variance_and_correlation_time_match_the_configuration(tau_over_h):
    h, sigma = 10.0, 2.5
    tau = tau_over_h * h
    x = knots(h, sigma, tau, seed=7)
    assert np.all(np.isfinite(x))
    phi = math.exp(-h / tau)
    var = float(np.var(x))
    sd_rel = math.sqrt(2.0 * (1.0 + phi**2) / ((1.0 - phi**2) * N))
    assert abs(var / sigma**2 - 1.0) <= K * sd_rel, (var, sigma**2, sd_rel)
    xc = x - x.mean()
    rho = float(xc[1:] @ xc[:-1] / (xc @ xc))
    sd_rho = math.sqrt((1.0 - phi**2) / N)
    assert abs(rho - phi) <= K * sd_rho, (rho, phi, sd_rho)
    if phi > 0.05:  # a correlation time from the lag-1 correlation where it is resolvable
        tau_hat = -h / math.log(rho)
        sd_tau = tau * sd_rho / (phi * abs(math.log(phi)))
        assert abs(tau_hat - tau) <= K * sd_tau, (tau_hat, tau, sd_tau)


def test_the_recursion_is_the_ar1_recursion():
    """lfilter with its initial state runs x_i = a x_{i-1} + w_i from the given x_0."""
    rng = np.random.default_rng(3)
    for a in (0.0, 1e-300, 0.057, 0.5, 0.9944, 1.0):
        w = rng.standard_normal(1000)
        x, want = 0.7, np.empty(1000)
        for i, wi in enumerate(w):
            x = a * x + wi
            want[i] = x
        assert np.allclose(_ar1(a, 0.7, w), want, rtol=1e-12, atol=1e-12)


def test_the_recursion_gives_lfilters_bits():
    """The loop that replaced scipy.signal.lfilter (issue 17: not imported at start) gives
    the same bits, so every record drawn from a Gauss-Markov process is unchanged."""
    from scipy.signal import lfilter

    rng = np.random.default_rng(17)
    for a in (0.0, 1e-300, 0.057, 0.5, 0.9944, 0.999999, 1.0):
        for scale in (1e-15, 1e-6, 1.0, 1e3):
            w = rng.standard_normal(4096) * scale
            x = float(rng.standard_normal()) * scale
            want, _ = lfilter([1.0], [1.0, -a], w, zi=[a * x])
            assert np.array_equal(_ar1(a, x, w), want)


@pytest.mark.parametrize(("h", "tau"), [(60.0, 21.0), (10.0, 3.5), (10.0, 1e-3), (60.0, 1e12)])
def test_finite_where_the_closed_form_gave_nan(h, tau):
    """The issue's values: the pier wander's 60-s knots with tau 21 s and a gyro drift's
    10-s knots with tau 3.5 s stopped the day ('cannot convert float NaN to integer')."""
    p = gauss_markov(h, 1.0, tau, 11, "env", "wander", "E")
    t = np.linspace(0.0, 86400.0, 5001)
    assert np.all(np.isfinite(p.value(t)))
    assert np.all(np.isfinite(p.integral(t)))


def test_between_knots_the_variance_is_what_the_bound_allows():
    """At ten knots per time constant (the configuration's lower bound) the variance at
    mid-knot is sigma^2 (1 + phi) / 2, within 5 % of sigma^2."""
    h, sigma = 10.0, 1.0
    tau = 10 * h
    p = gauss_markov(h, sigma, tau, 5, "test", "mid")
    mid = np.asarray(p.value((np.arange(N - 1) + 0.5) * h))
    phi = math.exp(-h / tau)
    want = sigma**2 * (1.0 + phi) / 2.0
    assert abs(want - sigma**2) <= 0.05 * sigma**2
    sd_rel = math.sqrt(2.0 * (1.0 + phi**2) / ((1.0 - phi**2) * N))
    assert abs(float(np.var(mid)) / want - 1.0) <= K * sd_rel


def test_time_constants_shorter_than_ten_knots_are_refused():
    """Ten knots per time constant at least (60-s knots of the wander, 10-s of the drift)."""
    with pytest.raises(ConfigError) as e:
        load_config(overrides={"environment": {"pier_tilt": {"wander_tau_s": 21.0}}})
    assert ("environment.pier_tilt.wander_tau_s: Input should be greater than or equal to "
            "600 (got 21.0)") in str(e.value)
    gyros = default_dict()["isu"]["gyros"]
    gyros[1]["drift_tau_s"] = 3.5
    with pytest.raises(ConfigError) as e:
        load_config(overrides={"isu": {"gyros": gyros}})
    assert ("isu.gyros.1.drift_tau_s: Input should be greater than or equal to 100 "
            "(got 3.5)") in str(e.value)
    cfg = load_config(overrides={"environment": {"pier_tilt": {"wander_tau_s": 600.0}}})
    assert cfg.environment.pier_tilt.wander_tau_s == 600.0
