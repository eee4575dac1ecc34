"""Random admissible laboratories (common to the issue-19 accuracy tests and bench): a site
at 5-70 deg latitude in either hemisphere, the ISU's coefficients redrawn at 0.3-3x with a
random sign, the instrument noise and the pier's wobble and wander at 0.3-3x (one factor
per laboratory)."""

from __future__ import annotations

import numpy as np

from station.config.isu import StationConfig, default_dict, load_config

GYRO_COEFS = ("R_deg_hr", "B_I_deg_hr_g", "B_O_deg_hr_g", "B_S_deg_hr_g", "C_II_deg_hr_g2",
              "C_SS_deg_hr_g2", "C_IS_deg_hr_g2", "C_OS_deg_hr_g2", "C_IO_deg_hr_g2",
              "Q_II_hr_deg", "Q_IS_hr_deg", "J_hr", "spin_axis_rotation_arcsec")
ACCEL_COEFS = ("D0_g", "D2_g_per_g2", "D3_g_per_g3")


def _redraw(rng: np.random.Generator, x: float) -> float:
    return float(x * rng.uniform(0.3, 3.0) * rng.choice([-1.0, 1.0]))


def random_overrides(rng: np.random.Generator, *, redraw_isu: bool = True,
                     noise: float | None = None) -> dict:
    """Config overrides of one random admissible laboratory; ``noise``: the noise factor
    (drawn in 0.3-3 when None)."""
    isu = default_dict()["isu"]
    f = float(rng.uniform(0.3, 3.0)) if noise is None else noise
    lat = float(rng.uniform(5.0, 70.0) * rng.choice([-1.0, 1.0]))
    gyros, accels = [], []
    for g in isu["gyros"]:
        g = dict(g)
        if redraw_isu:
            for k in GYRO_COEFS:
                g[k] = _redraw(rng, g[k])
            g["misalignment_arcsec"] = [_redraw(rng, x) for x in g["misalignment_arcsec"]]
        g["arw_deg_rt_hr"] *= f
        g["drift_sigma_deg_hr"] *= f
        gyros.append(g)
    for a in isu["accels"]:
        a = dict(a)
        if redraw_isu:
            for k in ACCEL_COEFS:
                a[k] = _redraw(rng, a[k])
            a["misalignment_arcsec"] = [_redraw(rng, x) for x in a["misalignment_arcsec"]]
        a["noise_micro_g_rt_hz"] *= f
        accels.append(a)
    env = default_dict()["environment"]
    environment = {"wobble": {"amplitude_arcsec": env["wobble"]["amplitude_arcsec"] * f},
                   "pier_tilt": {"wander_sigma_arcsec":
                                 env["pier_tilt"]["wander_sigma_arcsec"] * f}}
    return {"site": {"latitude_deg": lat}, "isu": {"gyros": gyros, "accels": accels},
            "environment": environment}


def random_station(seed: int, **kw: object) -> StationConfig:
    """The station config of laboratory ``seed`` (its own rng; the run's seed too)."""
    rng = np.random.default_rng(10_000 + seed)
    return load_config(seed=seed, overrides=random_overrides(rng, **kw))  # type: ignore[arg-type]
