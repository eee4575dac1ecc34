"""Random admissible laboratories for the calibration tests and bench scripts (issue 19).

``random_lab(seed)``: latitude 5-70 deg in either hemisphere, every ISU coefficient (and
misalignment) redrawn at 0.3-3x with random sign, gyro and accelerometer noise at 0.3-3x
(one factor each, the lab's NoiseSpec). ``calibration_day(cfg)``: only the position charts
(II-6, II-11..II-14) measured unless told, as (CalibrationData, NoiseSpec, truth, II-7
speed series) documents.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from laboratory.isu.spec import noise_spec, site_of
from laboratory.isu.truth import calibration_truth
from procedures.isu.computations import calibration_data
from procedures.isu.day import measure_day
from procedures.isu.plan import DayPlan
from procedures.journal import Journal
from procedures.runner import Run
from station.config.isu import StationConfig, default_dict, load_config
from station.racks.isu import SimulatedRack, open_isu_drivers

POSITION_CHARTS = ("II-6", "II-11", "II-12", "II-13", "II-14")
GYRO_COEFS = ("R_deg_hr", "B_I_deg_hr_g", "B_O_deg_hr_g", "B_S_deg_hr_g", "C_II_deg_hr_g2",
              "C_SS_deg_hr_g2", "C_IS_deg_hr_g2", "C_OS_deg_hr_g2", "C_IO_deg_hr_g2",
              "Q_II_hr_deg", "Q_IS_hr_deg", "J_hr")
ACCEL_COEFS = ("D0_g", "D2_g_per_g2", "D3_g_per_g3")


def random_lab(seed: int) -> StationConfig:
    """A random admissible laboratory (module docstring)."""
    rng = np.random.default_rng(10_000 + seed)
    isu = default_dict()["isu"]

    def redraw(v: float) -> float:
        return float(v * rng.uniform(0.3, 3.0) * rng.choice([-1.0, 1.0]))

    gyro_noise, accel_noise = rng.uniform(0.3, 3.0, size=2)  # one NoiseSpec per lab
    gyros = []
    for g in isu["gyros"]:
        g = dict(g)
        for name in GYRO_COEFS:
            g[name] = redraw(g[name])
        g["J_hr"] = abs(g["J_hr"])
        g["misalignment_arcsec"] = [redraw(x) for x in g["misalignment_arcsec"]]
        g["arw_deg_rt_hr"] *= gyro_noise
        g["drift_sigma_deg_hr"] *= gyro_noise
        gyros.append(g)
    accels = []
    for a in isu["accels"]:
        a = dict(a)
        for name in ACCEL_COEFS:
            a[name] = redraw(a[name])
        a["misalignment_arcsec"] = [redraw(x) for x in a["misalignment_arcsec"]]
        a["noise_micro_g_rt_hz"] *= accel_noise
        accels.append(a)
    lat = float(rng.uniform(5.0, 70.0) * rng.choice([-1.0, 1.0]))
    return load_config(seed=seed, overrides={"site": {"latitude_deg": lat},
                                             "isu": {"gyros": gyros, "accels": accels}})


def calibration_day(cfg: StationConfig, charts: tuple[str, ...] = POSITION_CHARTS,
                    plan: DayPlan | None = None) -> tuple[dict, dict, dict, dict]:
    """(CalibrationData as JSON, NoiseSpec as JSON, truth, the II-7 speed series) of the
    lab's ``charts`` (default the position charts only) under ``plan`` (default DayPlan())."""
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            run = Run(st.clock, Journal(Path(tmp) / "journal.jsonl"))
            plan, site, noise = plan or DayPlan(), site_of(cfg), noise_spec(cfg)
            data = measure_day(st, run, plan, site, cfg.isu.accels[0].f0_hz,
                               only=charts, noise=noise)
            cd = calibration_data(data, plan, site)
        truth = {f"{i}|{p}": v for (i, p), v in calibration_truth(rack.world).items()}
        series = {str(k): v for k, v in data.nonlinearity.items()}
        return cd.model_dump(mode="json"), noise.model_dump(mode="json"), truth, series
    finally:
        st.close()
        rack.close()

