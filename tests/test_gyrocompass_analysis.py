"""Gyrocompassing accuracy test analysis (report 001, eqs. 7, 14-25, section 5.4)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from procedures.cigtf.analysis import orientation_values, phase_values, run_values
from procedures.cigtf.scale import (
    ARCSEC_PER_RAD,
    REPORT_LATITUDE_DEG,
    gsf_constant,
    gsf_from_scale_factor,
    gsf_from_turn,
    horizontal_earth_rate,
)
from procedures.cigtf.significance import (
    f_threshold,
    judge,
    mean_t_test,
    noise_f_test,
    shutdown_f_test,
    t_threshold,
)

GSF = 4.0  # arcsec per ma


def _currents(phi_arcsec: float, s_t: float, lat: float, drift: float, d_o: float) -> list[float]:
    """True mean currents of orientations 1-4 from eqs. 1-4 (deg/hr, ma)."""
    w = horizontal_earth_rate(lat)
    phi = phi_arcsec / ARCSEC_PER_RAD
    return [(-phi * w + drift + d_o) / s_t, (phi * w + drift + d_o) / s_t,
            (-phi * w + drift - d_o) / s_t, (phi * w + drift - d_o) / s_t]


def _run_samples(rng: np.random.Generator, theta: float, noise: float, m: int = 10):
    """Samples of a run whose true theta (arcsec at GSF) is ``theta``."""
    base = np.array([5.0 + theta / (4 * GSF), 5.0 - theta / (4 * GSF),
                     3.0 + theta / (4 * GSF), 3.0 - theta / (4 * GSF)])
    return [b + noise * rng.standard_normal(m) for b in base]


def _phase(rng, n, theta, noise, run_sd=0.0):
    runs = [run_values(_run_samples(rng, theta + run_sd * rng.standard_normal(), noise), GSF)
            for _ in range(n)]
    return phase_values(runs)


def test_eq7_constant_at_report_site():
    assert horizontal_earth_rate(REPORT_LATITUDE_DEG) == pytest.approx(12.59562, abs=1e-9)
    assert gsf_constant() == pytest.approx(4093.979, abs=1e-3)
    assert gsf_constant(0.0) == pytest.approx(ARCSEC_PER_RAD / 60.0)


@pytest.mark.parametrize("lat", [0.0, REPORT_LATITUDE_DEG, 60.0])
def test_one_degree_turn_gives_gsf_and_theta_at_any_latitude(lat):
    s_t, phi = 0.035, 12.5
    i = _currents(phi, s_t, lat, drift=0.7, d_o=0.3)
    w = horizontal_earth_rate(lat)
    i1_turned = i[0] - math.radians(1.0) * w / s_t  # eq. 10
    gsf = gsf_from_turn(i[0], i1_turned)
    assert gsf == pytest.approx(900.0 / (i[0] - i1_turned))
    assert gsf == pytest.approx(gsf_from_scale_factor(s_t, lat), rel=1e-12)
    run = run_values([[x, x] for x in i], gsf)
    assert run.theta == pytest.approx(-phi, abs=1e-9)  # phi' = phi - theta, a + d = 0


def test_turn_without_change_is_refused():
    with pytest.raises(ValueError):
        gsf_from_turn(1.0, 1.0)


def test_orientation_values_eqs_15_to_17():
    x = [1.0, 2.0, 4.0, 7.0]
    o = orientation_values(x)
    assert o.mean == pytest.approx(3.5)
    assert o.variance == pytest.approx(sum((v - 3.5) ** 2 for v in x) / 3)
    assert o.variance_of_mean == pytest.approx(o.variance / 4)


def test_run_values_eqs_18_19():
    s = [[1.0, 1.2], [0.5, 0.5], [2.0, 2.4], [0.1, 0.3]]
    r = run_values(s, GSF)
    assert r.theta == pytest.approx(GSF * (1.1 + 2.2 - 0.5 - 0.2))
    vm = [np.var(v, ddof=1) / 2 for v in s]
    assert r.sigma == pytest.approx(GSF * math.sqrt(sum(vm)))
    assert r.noise_dof == 4


def test_phase_values_eqs_20_to_25():
    rng = np.random.default_rng(1)
    runs = [run_values(_run_samples(rng, 3.0, 0.01), GSF) for _ in range(5)]
    p = phase_values(runs)
    th = [r.theta for r in runs]
    assert p.theta == pytest.approx(np.mean(th))
    assert p.sigma == pytest.approx(math.sqrt(sum(r.sigma**2 for r in runs)) / 5)
    assert p.s == pytest.approx(math.sqrt(sum(r.sigma**2 for r in runs) / 5))
    assert p.s == pytest.approx(math.sqrt(5) * p.sigma)  # eq. 23
    assert p.instability == pytest.approx(np.std(th, ddof=1))


def test_report_thresholds_come_from_the_actual_dof():
    rng = np.random.default_rng(2)
    op = _phase(rng, 25, 1.0, 0.02)
    sd = _phase(rng, 10, 1.0, 0.02)
    assert op.noise_dof == 900 and sd.noise_dof == 360
    assert round(mean_t_test(op, corrected=False).threshold, 2) == 1.96
    f1, f2, f3 = noise_f_test(op), noise_f_test(sd), shutdown_f_test(op, sd)
    assert f1.dof == (24, 900) and round(f1.threshold, 2) == 1.53
    assert f2.dof == (9, 360) and round(f2.threshold, 2) == 1.91
    assert f3.dof == (9, 24) and round(f3.threshold, 2) == 2.30
    assert round(t_threshold(10**6), 2) == 1.96
    assert f_threshold(24, 900) == pytest.approx(1.5294, abs=1e-4)


def test_corrected_t_uses_instability_and_n_minus_1():
    rng = np.random.default_rng(3)
    op = _phase(rng, 25, 1.0, 0.02, run_sd=2.0)
    t = mean_t_test(op, corrected=True)
    assert t.dof == (24,)
    assert t.statistic == pytest.approx(abs(op.theta) / (op.instability / 5.0))
    assert t.threshold == pytest.approx(2.0639, abs=1e-4)


def test_monte_carlo_phase_standard_error_is_honest():
    rng = np.random.default_rng(4)
    trials = 400
    phases = [_phase(rng, 25, 2.0, 0.05) for _ in range(trials)]
    thetas = np.array([p.theta for p in phases])
    claimed = math.sqrt(np.mean([p.sigma**2 for p in phases]))
    # eq. 21 is honest when runs differ only by noise
    assert np.std(thetas, ddof=1) / claimed == pytest.approx(1.0, abs=0.1)
    assert np.mean(thetas) == pytest.approx(2.0, abs=4 * claimed / math.sqrt(trials))
    # the F test of 5.4.2 fires about 5 % of the time under the null
    rate = np.mean([noise_f_test(p).significant for p in phases])
    assert 0.01 < rate < 0.10


def test_monte_carlo_correction_restores_honesty_with_instability():
    rng = np.random.default_rng(5)
    trials, run_sd = 300, 1.0
    phases = [_phase(rng, 25, 0.0, 0.05, run_sd=run_sd) for _ in range(trials)]
    thetas = np.array([p.theta for p in phases])
    true_se = math.sqrt(run_sd**2 + np.mean([p.s**2 for p in phases])) / 5.0
    assert np.std(thetas, ddof=1) / true_se == pytest.approx(1.0, abs=0.12)
    reports = [judge(p, p) for p in phases]
    assert np.mean([r.operating.noise_test.significant for r in reports]) > 0.95
    used = math.sqrt(np.mean([r.operating.standard_error**2 for r in reports]))
    assert used / true_se == pytest.approx(1.0, abs=0.1)
    naive = math.sqrt(np.mean([p.sigma**2 for p in phases]))
    assert naive < 0.5 * true_se  # eq. 21 alone would understate
    # corrected t test keeps its 5 % size when theta is truly zero
    rate = np.mean([r.operating.mean_test.significant for r in reports])
    assert rate < 0.10


def test_quantiles_agree_with_scipy():
    """procedures.quantiles (no scipy at run time) against scipy.special over the dof and
    levels a gyrocompassing test can ask for, including one-sided extremes."""
    from scipy.special import fdtri, stdtrit

    from procedures.quantiles import f_quantile, t_quantile

    for dfn in (1, 2, 5, 9, 24, 34, 100, 900, 5000):
        for dfd in (1, 3, 9, 24, 35, 360, 900, 10_000):
            for p in (0.1, 0.5, 0.9, 0.95, 0.99, 0.999):
                assert f_quantile(p, dfn, dfd) == pytest.approx(fdtri(dfn, dfd, p), rel=1e-9)
    for dof in (1, 2, 5, 10, 24, 34, 360, 10**6):
        for p in (0.6, 0.95, 0.975, 0.995, 0.9995):
            assert t_quantile(p, dof) == pytest.approx(stdtrit(dof, p), rel=1e-9)
            assert t_quantile(1.0 - p, dof) == pytest.approx(stdtrit(dof, 1.0 - p), rel=1e-9)
