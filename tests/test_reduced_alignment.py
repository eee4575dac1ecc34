"""Alignments with fewer instruments (III-2.2, III-3.2; procedures.isu.alignment.reduced).

(a) Noise-free components at random attitudes near position 0 and random latitudes (both
    hemispheres, 5-70 deg): the reduced gyrocompass solution and the completed level vector
    give the true attitude; sets that leave a rotation undetermined are refused.
(b) With noise on the estimated g and omega^E, the spread of the reduced solutions over 3000
    draws matches the covariance the Jacobians predict (the error model of the alignments).
(c) On the simulated laboratory (a site and noise drawn at random): level with two
    accelerometers and the gyrocompass with 2 + 1 and 1 + 2 instruments, errors within 4
    predicted sigma of the simulator's attitude; refusals name the instruments.
"""

from __future__ import annotations

import json
import math
import random

import numpy as np
import pytest
from rich.console import Console
from scipy.spatial.transform import Rotation

from laboratory.isu.align import AlignRequest, command_plan, run_align
from laboratory.isu.day import DayRequest, run_day
from laboratory.pytest_plugin import virtual_station
from procedures.isu.alignment import error_model as em
from procedures.isu.alignment.reduced import (
    Instruments,
    check_gyrocompass_set,
    check_level_set,
    complete_gravity,
    gyrocompass_attitude,
)
from procedures.runner import ProcedureError
from station.errors import CheckFailed

QUIET = Console(quiet=True)
POSITION0 = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # B1 E, B2 N, B3 U
G, W = 9.80382, 15.041
GOOD = [((1, 2), (1,)), ((1,), (1, 2)), ((1,), (1, 3)), ((1, 2), (1, 3)), ((1, 2, 3), (1,))]
BAD = [((1, 2), (2,)), ((1, 2), (3,)), ((3,), (1, 2)), ((1,), (2, 3)), ((2,), (1, 3))]


def _truth(rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """An attitude within a few arcmin of position 0 and a colatitude (deg)."""
    t = Rotation.from_rotvec(rng.normal(scale=1e-3, size=3)).as_matrix() @ POSITION0
    lat = rng.uniform(5.0, 70.0) * rng.choice([-1.0, 1.0])
    return t, 90.0 - lat


def _vectors(t: np.ndarray, colat: float) -> tuple[np.ndarray, np.ndarray]:
    c = math.radians(colat)
    return G * t[0], W * (math.cos(c) * t[0] + math.sin(c) * t[2])


def test_reduced_solutions_are_exact_without_noise():
    rng = np.random.default_rng(3)
    for _ in range(40):
        t, colat = _truth(rng)
        g_b, w_b = _vectors(t, colat)
        prior = Rotation.from_rotvec(rng.normal(scale=3e-4, size=3)).as_matrix() @ t
        for accels, gyros in GOOD:
            inst = Instruments(accels, gyros, prior)
            check_gyrocompass_set(inst, colat)
            got = gyrocompass_attitude(g_b, w_b, inst, G, W, colat)
            assert np.max(np.abs(got - t)) < 1e-9, (accels, gyros)
        for accels, gyros in BAD:
            with pytest.raises(CheckFailed, match="do not determine the attitude"):
                check_gyrocompass_set(Instruments(accels, gyros, prior), colat)
        # level: accelerometer 3 (vertical) left out, its component from |g|
        inst = Instruments((1, 2), (1, 2, 3), prior)
        check_level_set(inst)
        partial = g_b * np.array([1.0, 1.0, 0.0])
        assert np.allclose(complete_gravity(partial, inst, G) / G, t[0], atol=1e-12)
        for accels in ((1, 3), (2, 3)):
            with pytest.raises(CheckFailed, match="near the vertical"):
                check_level_set(Instruments(accels, (1, 2, 3), prior))


@pytest.mark.parametrize(("accels", "gyros"), [((1, 2), (1,)), ((1,), (1, 2))])
def test_reduced_gyrocompass_covariance_matches_monte_carlo(accels, gyros):
    rng = np.random.default_rng(sum(accels) * 10 + sum(gyros))
    t, colat = _truth(rng)
    g_b, w_b = _vectors(t, colat)
    inst = Instruments(accels, gyros, t)
    cov_g = np.diag([2e-5, 3e-5, 1e-5]) ** 2 * G**2  # m/s^2
    cov_w = np.diag([0.01, 0.02, 0.015]) ** 2  # deg/hr
    t0 = gyrocompass_attitude(g_b, w_b, inst, G, W, colat)
    j_g = em.jacobian(em.phi_of(t0, lambda g: gyrocompass_attitude(g, w_b, inst, G, W, colat)),
                      g_b, 1e-6)
    j_w = em.jacobian(em.phi_of(t0, lambda w: gyrocompass_attitude(g_b, w, inst, G, W, colat)),
                      w_b, 1e-5)
    predicted = j_g @ cov_g @ j_g.T + j_w @ cov_w @ j_w.T
    n = 3000
    errs = np.array([em.phi_of(t0, lambda x: x)(gyrocompass_attitude(
        g_b + rng.multivariate_normal(np.zeros(3), cov_g),
        w_b + rng.multivariate_normal(np.zeros(3), cov_w), inst, G, W, colat))
        for _ in range(n)])
    observed = np.cov(errs.T)
    # per axis: sample variance / predicted within the chi-square 99.9 % band for n draws
    lo, hi = 1 - 3.3 * math.sqrt(2 / n), 1 + 3.3 * math.sqrt(2 / n)
    ratio = np.diag(observed) / np.diag(predicted)
    assert np.all((lo < ratio) & (ratio < hi)), ratio


# ------------------------------------------------------------------------------------ (c)
@pytest.fixture(scope="module")
def calibration(tmp_path_factory):
    rng = random.Random(41)
    lat = rng.uniform(10.0, 65.0) * rng.choice([-1.0, 1.0])
    over = {"site.latitude_deg": lat}
    for i in range(3):
        over[f"isu.accels.{i}.noise_micro_g_rt_hz"] = rng.uniform(5.0, 20.0)
    st = virtual_station("isu", seed=rng.randrange(1, 10_000), overrides=over)
    out = tmp_path_factory.mktemp("reduced") / "day"
    run_day(DayRequest(st.cfg, out, quiet=True, align=False), QUIET)
    return out, st


SURVEY = {"surveyed_g": True, "surveyed_earth_rate": True, "known_colatitude": True}


@pytest.mark.parametrize(("method", "given"), [
    ("level", {"accels": (1, 2), "surveyed_g": True}),
    ("gyrocompass", {"accels": (1, 2), "gyros": (1,), **SURVEY}),
    ("gyrocompass", {"accels": (1,), "gyros": (1, 2), **SURVEY}),
])
def test_reduced_alignments_against_truth(calibration, tmp_path, method, given):
    day, st = calibration
    out = tmp_path / "run"
    res = run_align(AlignRequest(st.cfg, out, method, "average", calibration=day, quiet=True,
                                 warmup_s=60.0, plan=command_plan(st.cfg, method, given)),
                    QUIET)
    (e,) = res["alignment"]
    assert all(abs(z) < 4 for z in e["error_over_sigma"]), e
    sheet = json.loads((out / "sheets" / f"alignment_results_{method}_average.json").read_text())
    assert any("III-2.2" in n or "III-3.2" in n for n in sheet["notes"])
    # the set changes the geometry: 1 + 2 loses the east tilt's accelerometer
    if given.get("accels") == (1,):
        assert e["predicted_sigma_arcsec"][0] > 30 * e["predicted_sigma_arcsec"][1]


def test_reduced_refusals_name_the_instruments(calibration, tmp_path):
    day, st = calibration
    with pytest.raises(ValueError, match="--accels: two accelerometers need the surveyed"):
        command_plan(st.cfg, "level", {"accels": (1, 2)})
    with pytest.raises(ValueError, match="every survey input.*known_colatitude"):
        command_plan(st.cfg, "gyrocompass", {"gyros": (1,), "surveyed_g": True,
                                             "surveyed_earth_rate": True})
    plan = command_plan(st.cfg, "gyrocompass", {"accels": (1, 2), "gyros": (2,), **SURVEY})
    with pytest.raises(ProcedureError) as err:
        run_align(AlignRequest(st.cfg, tmp_path / "bad", "gyrocompass", "average",
                               calibration=day, quiet=True, warmup_s=60.0, plan=plan), QUIET)
    assert (err.value.chart, err.value.step) == ("III-8", "1")
    assert "accelerometers 1, 2 and gyros 2 do not determine the attitude" in str(err.value)
    plan = command_plan(st.cfg, "level", {"accels": (1, 2), "surveyed_g": True})
    with pytest.raises(ProcedureError, match="tape is made for three accelerometers"):
        run_align(AlignRequest(st.cfg, tmp_path / "post", "level", "posterior",
                               calibration=day, quiet=True, warmup_s=60.0, plan=plan), QUIET)
