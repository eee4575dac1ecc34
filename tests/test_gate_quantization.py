"""Quantization of a clock-gated gyro count with correlated edges (issue 18, Chart II-18):
the model (procedures.isu.calibration.quantization, covariance.gyro_quantization_var)
against a direct simulation of a sampled pulse train counted over a gate, and the day's
and the Predictor's sigma using it."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from rich.console import Console

from laboratory.isu.day import DayRequest, run_day
from laboratory.isu.verify import predictor
from procedures.isu.calibration import NoiseSpec
from procedures.isu.calibration.covariance import gyro_quantization_var
from procedures.isu.calibration.quantization import UNIFORM, fraction_variance
from procedures.isu.calibration.reduce import Record
from procedures.isu.plan import DayPlan
from station.config.isu import load_config

N_DRAWS = 400_000
F_S = 19200.0  # the default gyros' rebalance sampling rate
RHO = 15.0 * 3600.0 / 3.0  # pulses/s of a 3 arcsec/pulse gyro along the axis at 15 deg/s
S1 = 1e-6  # counter clock tick, s


@pytest.mark.parametrize("c0", [0.0, 0.3, 0.85])
@pytest.mark.parametrize("sigma", [0.0, 0.05, 0.2, 1.0])
def test_fraction_variance_matches_sampled_fractions(c0, sigma):
    """E[x (1 - x)], x = frac(c0 + sigma xi): the series against 400k draws (4 standard
    errors); sigma 0 gives c0 (1 - c0), sigma 1 the uniform 1/6."""
    rng = np.random.default_rng(18)
    x = np.mod(c0 + sigma * rng.standard_normal(N_DRAWS), 1.0)
    v = x * (1.0 - x)
    se = v.std() / math.sqrt(N_DRAWS)
    assert fraction_variance(c0, sigma) == pytest.approx(v.mean(), abs=4 * se + 1e-12)
    if sigma == 1.0:
        assert fraction_variance(c0, sigma) == pytest.approx(UNIFORM, abs=1e-9)


def simulated_count_error(gate_s: np.ndarray, smear: float, rng: np.random.Generator) -> np.ndarray:
    """Counts of a train of phase u + RHO t (+ noise over the gate) read at the last
    sampling instant before each edge of [0, T], minus RHO T: u and the sampling grid's
    offset uniform (a new seed), the noise Gaussian (the gyro's random walk and the pier
    over the gate, which spread the advance's fraction over more than a pulse)."""
    n = gate_s.size
    u = rng.uniform(size=n)
    off = rng.uniform(size=n) / F_S  # time from the last sampling instant back to t = 0
    s0 = -off
    s1 = s0 + np.floor((gate_s + off) * F_S) / F_S
    noise = smear * rng.standard_normal(n)
    count = np.floor(u + RHO * s1 + noise) - np.floor(u + RHO * s0)
    return count - RHO * gate_s - noise


@pytest.mark.parametrize("fraction", [0.0, 0.3])
def test_clock_gate_quantization_matches_direct_simulation(fraction):
    """A gate of 2 turns (48 s = 921,600 whole sampling periods, then 0.3 period more): the
    model's count variance with the sampling clock known (ppm 0) is 1/6 + (rho tau)^2
    c (1 - c); the old independent edges' 1/6 (1 + (rho tau)^2) is the same count with c
    uniform (the gate's fraction of a period unknown)."""
    rng = np.random.default_rng(1818)
    T = 48.0 + fraction / F_S
    rec = Record(("G", 1, 1), 0.0, T, T / S1)
    known = NoiseSpec(gyro_sample_clock_ppm=0.0)
    err = simulated_count_error(np.full(N_DRAWS, T), 0.6, rng)
    model = gyro_quantization_var(RHO, rec, known) * T**2
    se = err.var() * math.sqrt(2.0 / N_DRAWS)
    # the model takes T from the counter: c uncertain by a clock tick (0.02 period)
    assert model == pytest.approx(err.var(), abs=4 * se + 0.01)
    if fraction == 0.0:  # whole periods: the sampling term all but gone
        assert model < 0.18 < NoiseSpec().count_quantization_var * (1 + (RHO / F_S) ** 2)
    unknown = NoiseSpec()
    gates = 48.0 + rng.uniform(size=N_DRAWS) / F_S
    err_u = simulated_count_error(gates, 0.6, rng)
    model_u = gyro_quantization_var(RHO, rec, unknown) * T**2
    assert model_u == pytest.approx(err_u.var(), abs=4 * err_u.var() * math.sqrt(2.0 / N_DRAWS))


def test_day_and_predictor_sigma_use_the_correlated_edges(tmp_path):
    """Positions 1-6 at 2 turns with [calibration] gyro_sample_clock_ppm = 0 (the default):
    the day's own DeltaPhi sigma and `plan --verify`'s Predictor (the day's timeline) agree
    within 3 %, both below the independent edges' Predictor (ppm 1000) by the sampling term
    (about 13 %)."""
    cfg = load_config(seed=7)
    out = tmp_path / "day"
    run_day(DayRequest(cfg, out, only=("II-6",), plan=DayPlan(min_turns=2), align=False,
                       quiet=True), Console(quiet=True))
    rows = json.loads((out / "results.json").read_text())["calibration"]
    own = {r["instrument"]: r["sigma"] for r in rows if r["parameter"] == "DeltaPhi"}
    independent = {"calibration": {"gyro_sample_clock_ppm": 1000.0}}
    known, unknown = predictor(cfg), predictor(load_config(seed=7, overrides=independent))
    times = known.default.set("gyro 1-6", 2)
    for k in (1, 2, 3):
        p = known.sigma(known.covariance(times), f"gyro{k}", "DeltaPhi")
        q = unknown.sigma(unknown.covariance(times), f"gyro{k}", "DeltaPhi")
        assert p == pytest.approx(own[f"gyro{k}"], rel=0.03)
        assert 0.8 < p / q < 0.9


@pytest.mark.parametrize("fraction", [0.0, 0.5])
def test_fit_speed_series_quantization_matches_direct_simulation(fraction):
    """A Chart II-7 speed (gyro along the rotary axis at 15 deg/s, 4 turns: rho tau about one
    pulse a sample) in the all-positions fit's covariance: with the gyro's random walk, drift
    and the pier quiet, a rate's variance times the gate squared is the simulated count's.
    The fit left the sampling term out (1/6 alone: 2.3x short at half a period); over 200
    default days its DeltaPhi error/sigma was 1.057 (600 gyro-days)."""
    from procedures.isu.calibration.all_positions import SpeedPoint, speed_covariance

    rng = np.random.default_rng(1819)
    T = 96.0 + fraction / F_S
    quiet = NoiseSpec(gyro_sample_clock_ppm=0.0, gyro_arw_deg_rt_hr=0.0,
                      gyro_drift_sigma_deg_hr=0.0, tilt_diurnal_pp_arcsec=0.0,
                      tilt_wander_sigma_arcsec=0.0, wobble_amplitude_arcsec=0.0)
    point = SpeedPoint(1, 15.0, RHO, T, T / S1)
    model = float(speed_covariance([point], quiet, {1: 3.0 / 3600.0})[0, 0]) * T**2
    err = simulated_count_error(np.full(N_DRAWS, T), 0.6, rng)  # the advance spread
    se = err.var() * math.sqrt(2.0 / N_DRAWS)
    assert model == pytest.approx(err.var(), abs=4 * se + 0.01)
    assert model > 0.35 if fraction else model < 0.18
