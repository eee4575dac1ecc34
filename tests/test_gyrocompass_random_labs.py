"""The CIGTF gyrocompassing test (report 001) in random admissible laboratories.

Every quantity the ``[cigtf]`` section admits is drawn within its bounds
(station/config/cigtf.py): the fixture's level, perpendicularity and mount errors, the slew
rate, the DVM's averaging time, the latitude within the limit the level error sets and the
torquer current noise within the one the latitude sets. Each laboratory runs the whole test;
both phases' theta are within 4 of their sigma of the truth, and the rms of error/sigma over
the set is within its chi-square 99 % interval (the sigma neither optimistic nor padded).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from laboratory.cigtf.gyrocompassing import run_gyrocompass_test
from sim.cigtf.world import CigtfParams
from station.config.cigtf import (
    CigtfConfig,
    max_current_noise_ma,
    max_tan_latitude,
    params_from,
)

LABS = 10


def draw(rng: np.random.Generator) -> CigtfConfig:
    """One admissible ``[cigtf]`` section, each bound taken from the loader's own rules."""
    level = float(rng.uniform(0.0, 60.0))
    limit = math.degrees(math.atan(max_tan_latitude(level)))
    lat = float(rng.uniform(-limit, limit))
    noise = float(rng.uniform(0.0, max_current_noise_ma(lat, CigtfParams().model.s_t)))
    return CigtfConfig.model_validate({
        "level_sd_arcsec": level, "perpendicular_sd_arcsec": float(rng.uniform(0.0, 60.0)),
        "mount_sd_arcsec": float(rng.uniform(0.0, 600.0)),
        "slew_deg_s": float(rng.uniform(2.0, 60.0)), "average_s": float(rng.uniform(1.0, 14.0)),
        "latitude_deg": lat, "current_noise_ma": noise})


def test_theta_within_its_sigma_in_random_laboratories(tmp_path: Path) -> None:
    rng = np.random.default_rng(2026_1128)
    z: list[float] = []
    for i in range(LABS):
        cfg = draw(rng)
        res = run_gyrocompass_test(700 + i, tmp_path / f"lab{i}", params=params_from(cfg),
                                   limits=cfg.limits, eq27=cfg.eq27)
        truth = res["truth"]["theta_arcsec"]
        for p in res["phases"]:
            e = (p["theta_arcsec"] - truth) / p["sigma_arcsec"]
            assert abs(e) < 4.0, (i, cfg, p)
            z.append(e)
    assert len(z) == 2 * LABS
    rms = math.sqrt(sum(x * x for x in z) / len(z))
    lo, hi = (math.sqrt(chi2.ppf(q, len(z)) / len(z)) for q in (0.005, 0.995))
    assert lo < rms < hi, (rms, lo, hi, z)


@pytest.mark.parametrize("seed", range(3))
def test_the_drawn_sections_span_their_bounds(seed: int) -> None:
    """The draw reaches the admitted extremes' neighbourhood (not the default's)."""
    rng = np.random.default_rng(seed)
    cfgs = [draw(rng) for _ in range(200)]
    assert max(c.level_sd_arcsec or 0.0 for c in cfgs) > 55.0
    assert max(c.mount_sd_arcsec or 0.0 for c in cfgs) > 550.0
    assert max(abs(c.latitude_deg or 0.0) for c in cfgs) > 45.0
