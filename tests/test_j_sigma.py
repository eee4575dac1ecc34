"""The J experiment's predicted sigma (procedures.isu.j_term.JNoise, issue 19).

(a) The count quantization of back-to-back gates: a Monte Carlo of the gyro's fractional
    phase across the gaps (the end of one gate and the start of the next a few tens of ms
    apart) against ``gate_covariance``'s correlation -(q/2)(1 - 6 d(1 - d)).
(b) The pier's tilt through the gates (issue 19, i19j): the simulator's pier process
    (``sim.isu.environment``) at 3x the default wobble and wander, integrated through each
    gate's turning input axis, plus the quantization chain, against ``gate_covariance``'s
    weighted variance: the adjacent gates' tilt covariance must survive the chain's term.
(c) On the simulated laboratory at near-zero instrument noise (quantization only, where the
    independent-gates model was 1.3x optimistic): J within 4 predicted sigma on every gyro
    and the pooled error/sigma rms within its chi-square 99 % interval.
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

import numpy as np
from rich.console import Console
from scipy.stats import chi2

from laboratory.isu.day import DayRequest, run_day
from laboratory.isu.spec import noise_spec
from procedures.isu.calibration.noise_spec import ARCSEC
from procedures.isu.j_term import DEG, JNoise, gate_covariance, j_estimate, profile
from sim.isu.environment import Environment
from station.config.isu import default_dict, load_config

sys.path.insert(0, str(Path(__file__).parent))
from random_lab import random_overrides  # noqa: E402

DPHI = 3.0  # arcsec/pulse
G_R = np.array([8e-4, 0.6, -0.8])


def _records(gap: float, pairs: int = 4, oper: float = 0.004) -> list[dict]:
    """Up/down gate records, each gate ``gap`` s after the previous one ended."""
    recs, t = [], 100.0
    for _ in range(pairs):
        for w0, w1 in ((0.0, 10.0), (10.0, 0.0)):
            recs.append({"t_pos_s": t, "t_oper": {"2": oper}, "gate_s": 20.0,
                         "phi_start": 37.0, "w_start": w0, "w_end": w1, "t_cmd": 9.0,
                         "counts": {"2": 0}})
            t += 20.0 + gap
    return recs


def test_quantization_chain_matches_monte_carlo():
    rng = np.random.default_rng(5)
    q = 1.0 / 6.0
    noise = JNoise(q, 0.0, 0.0, 3600.0, rest_rate_deg_hr=1.3)
    for gap in (0.002, 0.02, 0.05):
        recs = _records(gap)
        cov = gate_covariance(recs, 2, DPHI, G_R, 10.0, 5.0, noise)
        # the advance of the phase over each gap, at the rate the covariance assumes
        d = []
        for j in range(len(recs) - 1):
            c = -cov[j, j + 1]
            # invert c = (q/2)(1 - 6 d(1 - d)) for the d in [0, 1/2] it implies
            d.append(0.5 - math.sqrt(max(0.25 - (1 - 2 * c / q) / 6, 0.0)))
        n = 200_000
        f_end = rng.uniform(size=(n, len(recs)))
        f_start = np.empty_like(f_end)
        f_start[:, 0] = rng.uniform(size=n)
        for j in range(1, len(recs)):
            f_start[:, j] = (f_end[:, j - 1] + d[j - 1]) % 1.0
        err = f_start - f_end  # count = floor(end) - floor(start)
        w = np.tile([1.0, -1.0], len(recs) // 2)
        observed = float(np.var(err @ w))
        predicted = float(w @ cov @ w)
        assert abs(observed / predicted - 1) < 0.02, (gap, observed, predicted)
    # back-to-back gates with no phase advance: the chain's (8n - 2)/12, not the 4n/12
    cov = gate_covariance(_records(0.0, oper=0.0), 2, DPHI, G_R, 10.0, 5.0, noise)
    w = np.tile([1.0, -1.0], 4)
    assert abs(float(w @ cov @ w) - (8 * 4 - 2) / 12) < 1e-12


def test_j_sigma_without_gate_times_is_the_independent_model():
    recs = _records(0.02)
    for r in recs:
        del r["t_pos_s"]
    noise = JNoise(1 / 6, 0.1, 0.005, 3600.0)
    _, s = j_estimate(recs, 2, DPHI, G_R, 10.0, 5.0, noise)
    var_gate = 1 / 6 + 0.1 + (0.005 * 20.0 / DPHI) ** 2
    expect = math.sqrt(8 * var_gate) * DPHI / 3600.0 / 20.0 / 3600.0 / 4
    assert abs(s / expect - 1) < 1e-12


def _restless_pier(factor: float) -> dict:
    """Config overrides scaling the wobble and the tilt wander as random_lab's pier factor."""
    env = default_dict()["environment"]
    return {"environment": {
        **env,
        "wobble": {**env["wobble"],
                   "amplitude_arcsec": env["wobble"]["amplitude_arcsec"] * factor},
        "pier_tilt": {**env["pier_tilt"],
                      "wander_sigma_arcsec": env["pier_tilt"]["wander_sigma_arcsec"] * factor}}}


def _gate_nodes(recs: list[dict], counter: int, accel: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per gate, Gauss nodes (absolute times), weights and the horizontal input axis (E, N)
    there: the gyro's tilt angle is the sum of weight * (tilt rate . G) over its nodes."""
    x, w = np.polynomial.legendre.leggauss(24)
    ts, ws, ge, gn = [], [], [], []
    for r in recs:
        prof = profile(r["phi_start"], r["w_start"], r["w_end"], accel, r["t_cmd"])
        t0 = r["t_oper"][str(counter)]
        cuts = [t0, *prof.breaks, t0 + r["gate_s"]]
        t = np.concatenate([0.5 * (b - a) * x + 0.5 * (a + b)
                            for a, b in zip(cuts[:-1], cuts[1:], strict=True)])
        ws.append(np.concatenate([0.5 * (b - a) * w
                                  for a, b in zip(cuts[:-1], cuts[1:], strict=True)]))
        p = np.array([prof(float(u)) for u in t]) * DEG
        ge.append(G_R[1] * np.cos(p) - G_R[2] * np.sin(p))
        gn.append(G_R[1] * np.sin(p) + G_R[2] * np.cos(p))
        ts.append(r["t_pos_s"] + t)
    return np.array(ts), np.array(ws), np.array(ge), np.array(gn)


def test_j_sigma_keeps_the_piers_correlation_across_gates():
    cfg = load_config(overrides=_restless_pier(3.0))
    spec = noise_spec(cfg)
    accel, n_days = 5.0, 300
    recs = _records(0.0, oper=0.0)  # back to back: the chain's correlation is q/2
    for i, r in enumerate(recs):  # the table turns 100 deg in each gate, as in II-10
        r["t_pos_s"] += 5000.0
        r["phi_start"] = 37.0 + 100.0 * i
    noise = JNoise(1 / 6, 0.0, 0.0, 3600.0, pier=spec)
    w = np.tile([1.0, -1.0], 4)
    predicted = float(w @ gate_covariance(recs, 2, DPHI, G_R, 10.0, accel, noise) @ w)
    ts, ws, ge, gn = _gate_nodes(recs, 2, accel)
    rng = np.random.default_rng(19)
    sums = []
    for seed in range(1, n_days + 1):
        env = Environment(cfg.world_params().environment, seed)
        _, rate = env.tilt_and_rate(ts.ravel())
        rate_e, rate_n = (rate[:, k].reshape(ts.shape) for k in (1, 2))
        tilt = np.sum(ws * (rate_e * ge + rate_n * gn), axis=1) / ARCSEC / DPHI  # pulses
        phase = rng.uniform(size=len(recs) + 1)  # one floor shared at each gate boundary
        sums.append(float(w @ (tilt + phase[:-1] - phase[1:])))
    observed = float(np.mean(np.square(sums)))
    # the tilt as large as the quantization chain (alone is (8n - 2)/12 = 2.5 pulse^2)
    assert predicted > 1.5 * (8 * 4 - 2) / 12, predicted
    assert abs(observed / predicted - 1) < 0.2, (observed, predicted)


def test_j_within_its_sigma_at_quantization_level():
    z = []
    for seed in range(1, 13):
        rng = np.random.default_rng(10_000 + seed)
        over = random_overrides(rng, redraw_isu=seed % 2 == 0, noise=0.05)
        cfg = load_config(seed=seed, overrides=over)
        with tempfile.TemporaryDirectory() as d:
            res = run_day(DayRequest(cfg, Path(d) / "day", only=("II-6", "II-10"),
                                     align=False, quiet=True), Console(quiet=True))
        z += [r["error"] / r["sigma"] for r in res["calibration"]
              if r["parameter"] == "J" and r.get("sigma")]
    assert len(z) == 36 and max(abs(x) for x in z) < 4, z
    rms = math.sqrt(sum(x * x for x in z) / len(z))
    lo, hi = (math.sqrt(chi2.ppf(p, len(z)) / len(z)) for p in (0.005, 0.995))
    assert lo < rms < hi, (rms, lo, hi)
