"""The reconstructed posterior-mean level estimator of Charts I-9 / I-10 and its tape.

(a) M, b and A^-1 against a brute-force Bayesian computation built here on a fine time grid;
(b) the posterior mean never loses to the simple average, and by how much it wins under the
    lab's default NoiseSpec; (c) Monte Carlo with the exact (rotational) model; (d) the
    tape round trip and the operator's check of III-2.3.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from procedures.isu.alignment.estimation import (
    ARCSEC,
    MICRO_G,
    CovarianceTable,
    LevelParams,
    TiltCovarianceTable,
    chart_i9_quantities,
    covariance_of_average,
    hybrid_gyrocompass,
    level_params_from_noise_spec,
    posterior_level,
    predicted_level_sigma_arcsec,
    prior_mean,
    simple_average,
    tilt_coefficients,
)
from procedures.isu.alignment.parameter_sheet import (
    AlignmentParameterSheet,
    check_tape,
    make_tape,
    read_tape,
    write_tape,
)
from procedures.isu.calibration.noise_spec import NoiseSpec

G = 9.80382
UP = np.array([1.0, 0.0, 0.0])


# ---------------------------------------------------------------------------------------------
# An analytic noise model (smooth covariance functions) used by (a) and (c)
# ---------------------------------------------------------------------------------------------
def rodrigues(v: np.ndarray) -> np.ndarray:
    th = float(np.linalg.norm(v))
    if th == 0.0:
        return np.eye(3)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / th
    return np.eye(3) + math.sin(th) * k + (1 - math.cos(th)) * (k @ k)


def attitude(seed: int) -> np.ndarray:
    """A proper rotation: T1[i, k] = E_i . B_k."""
    rng = np.random.default_rng(seed)
    return rodrigues(rng.normal(size=3))


S1, L1, SD, PD, S2, L2, RHO = 3 * ARCSEC, 40.0, 1 * ARCSEC, 7.0, 2 * ARCSEC, 10.0, 0.4
SA, LA, FA = 50 * MICRO_G, 0.4, 1.5
Q_WHITE, SC, LC = (10 * MICRO_G) ** 2, 5 * MICRO_G, 0.3
STEPS_PER_S = 128  # table spacing and brute-force grid, 1/128 s (Simpson both ways)


def r1(t):
    t = np.abs(t)
    return S1**2 * np.exp(-0.5 * (t / L1) ** 2) + SD**2 * np.cos(2 * np.pi * t / PD)


def r2(t):
    return S2**2 * np.exp(-0.5 * (np.asarray(t) / L2) ** 2)


def tilt_ee(t):  # theta_E = u1, theta_N = RHO u1 + u2 (u1, u2 independent)
    return r1(t)


def tilt_nn(t):
    return RHO**2 * r1(t) + r2(t)


def tilt_en(t):
    return RHO * r1(t)


def vib(t):
    t = np.asarray(t)
    return SA**2 * np.exp(-0.5 * (t / LA) ** 2) * np.cos(2 * np.pi * FA * t)


def accel_corr(t):
    return SC**2 * np.exp(-0.5 * (np.asarray(t) / LC) ** 2)


def analytic_params(K, dt, eps_t, sigma_g, sigma_theta, T1, per_dt=None) -> LevelParams:
    h = dt / (per_dt or round(STEPS_PER_S * dt))
    lags = np.arange(int(round((K * dt + eps_t + dt) / h)) + 2) * h

    def tab(f, white=0.0):
        return CovarianceTable(lags_s=tuple(lags), values=tuple(f(lags)), white=white)

    return LevelParams(
        dt=dt,
        K=K,
        g_tilde=G,
        sigma_g=sigma_g,
        T1=tuple(map(tuple, T1)),
        sigma_theta=sigma_theta,
        phi_n=tab(accel_corr, Q_WHITE),
        phi_alpha=tab(vib),
        phi_theta=TiltCovarianceTable(
            lags_s=tuple(lags),
            east=tuple(tilt_ee(lags)),
            north=tuple(tilt_nn(lags)),
            cross=tuple(tilt_en(lags)),
        ),
        eps_t=eps_t,
    )


class Grid:
    """The record on a fine grid: Simpson weights of each interval, point t* at the end."""

    def __init__(self, K: int, dt: float, eps_t: float, n: int | None = None) -> None:
        n = n or round(STEPS_PER_S * dt)
        h = dt / n
        m = int(round(eps_t / h))
        assert abs(m * h - eps_t) < 1e-12
        self.t = np.arange(K * n + m + 1) * h
        self.W = np.zeros((K, self.t.size))
        w = np.ones(n + 1)
        w[1:-1:2], w[2:-1:2] = 4.0, 2.0
        for j in range(K):
            self.W[j, j * n : (j + 1) * n + 1] = w * h / 3
        self.lag = np.abs(self.t[:, None] - self.t[None, :])


def body_tilt_gradient(T1: np.ndarray, g: float) -> np.ndarray:
    """d(g_B)/d(theta_E, theta_N) by finite rotation of the body axes (3 x 2)."""
    out = np.zeros((3, 2))
    d = 1e-6
    for a in range(2):
        eps = np.zeros(3)
        eps[1 + a] = d
        plus = g * (rodrigues(eps) @ T1).T @ UP
        minus = g * (rodrigues(-eps) @ T1).T @ UP
        out[:, a] = (plus - minus) / (2 * d)
    return out


def brute_force(K, dt, eps_t, sigma_g, sigma_theta, T1):
    """Posterior of g_B(t*) given X from the joint Gaussian built on the grid."""
    gr = Grid(K, dt, eps_t)
    W, last = gr.W, -1
    phi = {k: f(gr.lag) for k, f in (("ee", tilt_ee), ("nn", tilt_nn), ("en", tilt_en))}
    pq = body_tilt_gradient(T1, G)
    # sources: g0 (3), theta_E(t*), Theta_E (K), theta_N(t*), Theta_N (K), N (3K)
    ns = 3 + 2 * (K + 1) + 3 * K
    cov = np.zeros((ns, ns))
    d = np.diag([sigma_g**2, (G * sigma_theta) ** 2, (G * sigma_theta) ** 2])
    cov[:3, :3] = T1.T @ d @ T1
    # the tilt functionals: row 0 the point t*, rows 1..K the interval integrals
    F = np.vstack((np.eye(gr.t.size)[last], W))
    blocks = {("E", "E"): phi["ee"], ("N", "N"): phi["nn"], ("E", "N"): phi["en"]}
    blocks[("N", "E")] = phi["en"].T
    off = {"E": 3, "N": 3 + K + 1}
    for (a, b), ph in blocks.items():
        cov[off[a] : off[a] + K + 1, off[b] : off[b] + K + 1] = F @ ph @ F.T
    noise = W @ (vib(gr.lag) + accel_corr(gr.lag)) @ W.T + Q_WHITE * dt * np.eye(K)
    n0 = 3 + 2 * (K + 1)
    for k in range(3):
        cov[n0 + k * K : n0 + (k + 1) * K, n0 + k * K : n0 + (k + 1) * K] = noise
    L = np.zeros((3 + 3 * K, ns))
    L[:3, :3] = np.eye(3)
    L[:3, off["E"]] = pq[:, 0]
    L[:3, off["N"]] = pq[:, 1]
    for k in range(3):
        for j in range(K):
            r = 3 + k * K + j
            L[r, k] = dt
            L[r, off["E"] + 1 + j] = pq[k, 0]
            L[r, off["N"] + 1 + j] = pq[k, 1]
            L[r, n0 + k * K + j] = 1.0
    joint = L @ cov @ L.T
    P = np.linalg.inv(joint)
    post_cov = np.linalg.inv(P[:3, :3])
    M = -post_cov @ P[:3, 3:]
    mu_y = G * T1.T @ UP
    mu_x = np.concatenate([dt * mu_y[k] * np.ones(K) for k in range(3)])
    return M, mu_y - M @ mu_x, post_cov


CASES = [
    # K, dt, eps_t, sigma_g, sigma_theta, attitude seed
    (3, 1.0, 0.0, 1e-2, 60 * ARCSEC, 1),
    (5, 0.5, 0.25, 1e-3, 10 * ARCSEC, 2),
    (6, 1.0, 0.75, 3e-3, 30 * ARCSEC, 3),
    (4, 2.0, 1.0, 1e-2, 120 * ARCSEC, 4),
]


# ---------------------------------------------------------------------------------------------
# (a) against the brute-force posterior
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("K, dt, eps_t, sg, sth, seed", CASES)
def test_posterior_equals_brute_force(K, dt, eps_t, sg, sth, seed):
    T1 = attitude(seed)
    params = analytic_params(K, dt, eps_t, sg, sth, T1)
    M, b, cov = posterior_level(params)
    Mb, bb, covb = brute_force(K, dt, eps_t, sg, sth, T1)
    assert M.shape == (3, 3 * K) and b.shape == (3,) and cov.shape == (3, 3)
    assert np.max(np.abs(M - Mb)) < 1e-6 * np.max(np.abs(Mb))
    assert np.max(np.abs(b - bb)) < 1e-6 * G
    assert np.max(np.abs(cov - covb)) < 1e-6 * np.max(np.abs(covb))
    # The literal Chart I-9/I-10 matrices give the same outputs: M = -A^-1 B,
    # b = a1 + A^-1 B a2, A^-1 the covariance of the estimate.
    c = chart_i9_quantities(params)
    assert np.allclose(c.M, M, rtol=0, atol=1e-8 * np.max(np.abs(M)))
    assert np.allclose(c.b, b, rtol=0, atol=1e-9 * G)
    assert np.allclose(np.linalg.inv(c.A), cov, rtol=0, atol=1e-8 * np.max(np.abs(cov)))
    assert c.V.shape == (3 + 3 * K, 3 + 3 * K + 2 * (K + 1))


def test_tilt_convention_matches_the_simulator():
    """The model's g_B = a1 + [p q] (theta_E, theta_N) is the simulator's T^BE g_E to first
    order, with T^BE = T1^T T^FE(eps) as sim.isu.world composes it (T1 = T^EB, columns B_k)."""
    from sim.frames import transform_of_rotated

    T1 = attitude(7)
    params = analytic_params(2, 1.0, 0.0, 1e-3, 10 * ARCSEC, T1, per_dt=8)
    a1, _ = prior_mean(params)
    pq = tilt_coefficients(params)
    for th in ((2e-5, 0.0), (0.0, -3e-5), (1e-5, 1.5e-5)):
        eps = np.array([0.0, *th])
        a_b = T1.T @ transform_of_rotated(eps) @ (G * UP)
        first_order = a1 + pq @ np.array(th)
        assert np.max(np.abs(a_b - first_order)) < G * float(np.dot(th, th))  # 2nd order
        assert np.max(np.abs(a_b - a1)) > 1e3 * G * float(np.dot(th, th))


def test_simple_average_and_hybrid():
    M, b = simple_average(4, 0.5)
    assert M.shape == (3, 12) and np.all(b == 0)
    X = np.concatenate([np.full(4, 0.5 * v) for v in (1.0, 2.0, 3.0)])
    assert np.allclose(M @ X, [1.0, 2.0, 3.0])
    M6, b6 = simple_average(4, 0.5, n_axes=6)
    assert M6.shape == (6, 24) and np.allclose(M6.sum(axis=1), 4 / (4 * 0.5))
    Mh, bh = hybrid_gyrocompass(np.ones((3, 12)), np.array([1.0, 2.0, 3.0]), 4, 0.5)
    assert Mh.shape == (6, 24) and np.allclose(Mh[3:, 12:], M) and np.all(Mh[:3, 12:] == 0)
    assert np.allclose(bh, [1, 2, 3, 0, 0, 0])


# ---------------------------------------------------------------------------------------------
# (b) posterior mean against simple average
# ---------------------------------------------------------------------------------------------
def _psd(m: np.ndarray) -> bool:
    return bool(np.min(np.linalg.eigvalsh(0.5 * (m + m.T))) >= -1e-9 * np.max(np.abs(m)))


@pytest.mark.parametrize("K, dt, eps_t, sg, sth, seed", CASES)
def test_posterior_never_worse_than_average_analytic(K, dt, eps_t, sg, sth, seed):
    params = analytic_params(K, dt, eps_t, sg, sth, attitude(seed))
    _, _, cov = posterior_level(params)
    assert _psd(covariance_of_average(K, dt, params) - cov)


LEVEL_T1 = np.column_stack(  # B1 horizontal at 30 deg from east, B2 up, B3 = B1 x B2
    (
        (0.0, math.cos(math.radians(30)), math.sin(math.radians(30))),
        (1.0, 0.0, 0.0),
        np.cross((0.0, math.cos(math.radians(30)), math.sin(math.radians(30))), (1, 0, 0)),
    )
)


def default_params(K, dt, eps_t=0.0, **kw) -> LevelParams:
    return level_params_from_noise_spec(
        NoiseSpec(),
        dt,
        K,
        g_tilde=G,
        sigma_g=1e-2,
        T1=LEVEL_T1,
        sigma_theta=60 * ARCSEC,
        eps_t=eps_t,
        **kw,
    )


def test_default_spec_posterior_against_average():
    g_body = G * LEVEL_T1[0, :]
    rows = []
    for K, dt in ((10, 1.0), (30, 1.0), (60, 1.0), (30, 2.0), (120, 0.5), (120, 1.0), (300, 1.0)):
        params = default_params(K, dt)
        M, b, cov = posterior_level(params)
        avg = covariance_of_average(K, dt, params)
        assert _psd(avg - cov)
        post_s = predicted_level_sigma_arcsec(cov, g_body)
        avg_s = predicted_level_sigma_arcsec(avg, g_body)
        rows.append((K, dt, post_s, avg_s))
        if (K, dt) == (60, 1.0):
            assert max(post_s) < 0.75 * min(avg_s)
    print("\nlevel sigma (arcsec, about h1 / h2), default NoiseSpec, prior 60 arcsec, eps_t = 0")
    for K, dt, p, a in rows:
        print(
            f"K={K:4d} dt={dt:4.1f}s  posterior {p[0]:.3f}/{p[1]:.3f}  "
            f"average {a[0]:.3f}/{a[1]:.3f}  ratio {p[0] / a[0]:.2f}"
        )


# ---------------------------------------------------------------------------------------------
# (c) Monte Carlo: exact rotations, processes drawn on the grid
# ---------------------------------------------------------------------------------------------
def _sqrt_psd(c: np.ndarray) -> np.ndarray:
    w, u = np.linalg.eigh(0.5 * (c + c.T))
    return u * np.sqrt(np.clip(w, 0.0, None))


def test_monte_carlo_error_matches_predicted_covariance():
    K, dt, eps_t, sg, sth = 8, 1.0, 0.5, 3e-3, 30 * ARCSEC
    T1 = attitude(11)
    params = analytic_params(K, dt, eps_t, sg, sth, T1)
    M, b, cov = posterior_level(params)
    gr = Grid(K, dt, eps_t, n=16)
    n = gr.t.size
    rng = np.random.default_rng(20240607)
    draws = 400
    u1 = _sqrt_psd(r1(gr.lag)) @ rng.standard_normal((n, draws))
    u2 = _sqrt_psd(r2(gr.lag)) @ rng.standard_normal((n, draws))
    th_e, th_n = u1, RHO * u1 + u2  # (n, draws)
    s_noise = _sqrt_psd(vib(gr.lag) + accel_corr(gr.lag))
    errors = np.empty((draws, 3))
    for d in range(draws):
        g_true = G + sg * rng.standard_normal()
        delta = np.array([0.0, *(sth * rng.standard_normal(2))])
        T_true = rodrigues(delta) @ T1  # true body axes (columns), untilted
        gb = np.empty((n, 3))
        for i in range(n):
            eps = np.array([0.0, th_e[i, d], th_n[i, d]])
            gb[i] = g_true * (rodrigues(eps) @ T_true).T @ UP
        noise = s_noise @ rng.standard_normal((n, 3))
        X = gr.W @ (gb + noise)  # (K, 3)
        X += math.sqrt(Q_WHITE * dt) * rng.standard_normal((K, 3))
        est = M @ X.T.reshape(-1) + b
        errors[d] = est - gb[-1]
    rms = np.sqrt(np.mean(errors**2, axis=0))
    ratio = rms / np.sqrt(np.diag(cov))
    print("\nMonte Carlo rms / predicted per body axis:", np.round(ratio, 3))
    assert np.all((ratio > 0.85) & (ratio < 1.2))
    # and whitened: E[e' C^-1 e] = 3
    maha = np.mean(np.einsum("di,ij,dj->d", errors, np.linalg.inv(cov), errors))
    assert 2.6 < maha < 3.5


# ---------------------------------------------------------------------------------------------
# (d) the tape
# ---------------------------------------------------------------------------------------------
def small_params(**update) -> LevelParams:
    p = default_params(5, 1.0, 0.5, vibration_max_lag_s=2.0)
    return p.model_copy(update=update) if update else p


def test_tape_round_trip_and_check(tmp_path):
    params = small_params()
    sheet = AlignmentParameterSheet(
        reel_id="APE-0001", prepared_by="test", date="1970-01-01", params=params
    )
    tape = make_tape(sheet)
    path = write_tape(tape, tmp_path / "ape.json")
    back = read_tape(path)
    assert back == tape
    M, b, cov = back.arrays()
    M0, b0, cov0 = posterior_level(params)
    assert np.array_equal(M, M0) and np.array_equal(b, b0) and np.array_equal(cov, cov0)
    check_tape(back, params)
    check_tape(back, sheet)
    # round-off is tolerated
    check_tape(back, small_params(dt=1.0 * (1 + 1e-13), g_tilde=G * (1 - 1e-14)))


def _refused(tape, params, name: str) -> str:
    with pytest.raises(ValueError) as info:
        check_tape(tape, params)
    msg = str(info.value)
    assert name in msg, msg
    return msg


def test_check_tape_refuses_other_parameters():
    params = small_params()
    tape = make_tape(AlignmentParameterSheet(reel_id="APE-0002", params=params))
    msg = _refused(tape, small_params(K=6), "K")
    assert "tape 5" in msg and "experiment 6" in msg
    msg = _refused(tape, small_params(dt=2.0), "dt")
    assert "1" in msg and "2" in msg
    _refused(tape, small_params(sigma_theta=30 * ARCSEC), "sigma_theta")
    _refused(tape, small_params(g_tilde=9.81), "g_tilde")
    t1 = np.asarray(params.T1)
    turned = tuple(map(tuple, rodrigues(np.array([0.0, 1e-4, 0.0])) @ t1))
    _refused(tape, small_params(T1=turned), "T1 differs")
    # a covariance table with one value changed, and one of another length
    vals = list(params.phi_alpha.values)
    vals[17] *= 1.01
    other = params.phi_alpha.model_copy(update={"values": tuple(vals)})
    msg = _refused(tape, small_params(phi_alpha=other), "phi_alpha.values[17]")
    assert "tape" in msg and "experiment" in msg
    longer = default_params(6, 1.0, 0.5, vibration_max_lag_s=2.0).phi_theta
    _refused(tape, small_params(phi_theta=longer), "phi_theta.lags_s")
    whiter = params.phi_n.model_copy(update={"white": params.phi_n.white * 4})
    _refused(tape, small_params(phi_n=whiter), "phi_n.white")
