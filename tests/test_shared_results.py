"""Results the day shares between its computations (issue 17) are the ones a fresh
computation gives, and no caller can change them for the next.

``estimation.joint`` (an alignment's estimator and error covariances), ``covariance.
tilt_grams`` (the fits of one day's data) and ``Constants.rho_matrix`` (the error models'
correlations, held by their keys) replaced repeated work; each must give the bits of the
work it replaced, for random inputs, not only the default lab's.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from procedures.isu.alignment.estimation import joint, level_params_from_noise_spec
from procedures.isu.alignment.preprocess import Constants
from procedures.isu.calibration.covariance import tilt_grams
from procedures.isu.calibration.kernels import Functional, band_nodes, cosine_gram, exp_gram
from procedures.isu.calibration.noise_spec import ARCSEC, DAY, NoiseSpec


@pytest.mark.parametrize("seed", range(6))
def test_rho_matrix_is_rho_pair_by_pair(seed):
    """Pairs listed in either order, both orders, a constant with itself, keys absent from
    the correlation and correlations of constants not asked for."""
    rng = np.random.default_rng(seed)
    names = [(f"gyro{k}", p) for k in (1, 2, 3) for p in ("R", "B_I", "DeltaPhi", "C_II")]
    pool = names + [("accel1", "D1")]
    corr = {}
    for _ in range(int(rng.integers(0, 80))):
        a, b = (pool[int(i)] for i in rng.integers(0, len(pool), 2))
        corr[(a, b)] = float(rng.uniform(-1, 1))
    c = Constants(dict.fromkeys(pool, 0.0), {}, corr)
    keys = [names[int(i)] for i in rng.permutation(len(names))[: int(rng.integers(1, 13))]]
    pairwise = np.array([[c.rho(a, b) for b in keys] for a in keys])
    assert np.array_equal(c.rho_matrix(keys), pairwise)
    # held for the next call, by these constants and those perturbed from them (the same
    # correlation), and read-only: no caller changes it for the next
    moved = c.perturbed(names[0], 0.5)
    assert moved.rho_matrix(keys) is c.rho_matrix(keys)
    assert np.array_equal(moved.rho_matrix(keys), pairwise)
    with pytest.raises(ValueError):
        c.rho_matrix(keys)[0, 0] = 2.0
    other = keys[::-1]  # other keys (their order too): built for them
    assert np.array_equal(c.rho_matrix(other),
                          np.array([[c.rho(a, b) for b in other] for a in other]))


@pytest.mark.parametrize("seed", range(4))
def test_joint_is_built_once_and_read_only(seed):
    rng = np.random.default_rng(seed)
    t1 = Rotation.from_rotvec(rng.normal(0, 1, 3)).as_matrix()
    noise = NoiseSpec(tilt_wander_sigma_arcsec=float(rng.uniform(0.2, 3.0)),
                      wobble_amplitude_arcsec=float(rng.uniform(0.1, 2.0)))
    params = level_params_from_noise_spec(
        noise, float(rng.uniform(0.5, 5.0)), int(rng.integers(3, 30)), g_tilde=9.80382,
        sigma_g=1e-2, T1=t1, sigma_theta=60 * ARCSEC, eps_t=float(rng.uniform(0, 1)),
        vibration_max_lag_s=2.0)
    shared = joint(params)
    assert joint(params.model_copy()) is shared  # an equal sheet: the same build
    fresh = joint.__wrapped__(params)
    for name in ("a1", "a2", "s_yy", "s_yx", "s_xx"):
        got = getattr(shared, name)
        assert np.array_equal(got, getattr(fresh, name)), name
        with pytest.raises(ValueError):
            got[0] = 0.0


@pytest.mark.parametrize("seed", range(4))
def test_tilt_grams_are_the_kernels_grams(seed):
    """Point values and gate means over a random day's span, under a random NoiseSpec."""
    rng = np.random.default_rng(seed)
    fs = []
    for _ in range(int(rng.integers(2, 25))):
        t0 = float(rng.uniform(0, 3e4))
        length = float(rng.uniform(1, 600))
        f = Functional.point(t0 + length, 1 / length) + Functional.point(t0, -1 / length)
        fs.append(f if rng.random() < 0.5 else Functional.mean(t0, t0 + length, 0.5) + f)
    nz = NoiseSpec(tilt_diurnal_pp_arcsec=float(rng.uniform(0, 20)),
                   tilt_wander_tau_s=float(rng.uniform(600, 3e4)),
                   wobble_period_s=float(rng.uniform(20, 200)),
                   wobble_coherence_s=float(rng.uniform(100, 2000)))
    diurnal, wander, wobble = tilt_grams(tuple(fs), nz)
    times = [t for f in fs for _, a, b in f.atoms for t in (a, b)]
    amp = 0.5 * nz.tilt_diurnal_pp_arcsec * ARCSEC
    assert np.array_equal(diurnal, cosine_gram(fs, np.array([1.0 / DAY]), np.array([1.0]))
                          * 0.5 * amp * amp)
    assert np.array_equal(wander, exp_gram(fs, nz.tilt_wander_tau_s)
                          * (nz.tilt_wander_sigma_arcsec * ARCSEC) ** 2)
    fb, df = 1.0 / nz.wobble_period_s, 1.0 / nz.wobble_coherence_s
    nodes, weights = band_nodes(fb - 0.5 * df, fb + 0.5 * df, max(times) - min(times))
    b = nz.wobble_amplitude_arcsec * ARCSEC
    assert np.array_equal(wobble, cosine_gram(fs, nodes, weights) * 0.5 * b * b)
    assert tilt_grams(tuple(fs), nz)[2] is wobble
    with pytest.raises(ValueError):
        wobble[0, 0] = 1.0
