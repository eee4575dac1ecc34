"""Random admissible laboratories for the calibration tests and bench scripts (issue 19).

``random_lab(seed)``: laboratory/isu/random_lab.py's laboratory ``seed`` (latitude 5-70 deg
in either hemisphere, every ISU coefficient and misalignment redrawn at 0.3-3x with random
sign, gyro, accelerometer and pier noise at 0.3-3x). ``calibration_day(cfg)``: only the
position charts (II-6, II-11..II-14) measured unless told, as (CalibrationData, NoiseSpec,
truth, II-7 speed series) documents. ``steep_station(seed)``: laboratory ``seed`` with the
gyros' B and every instrument axis's misalignment and spin-axis turn near their bounds.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from laboratory.isu.random_lab import random_station
from laboratory.isu.spec import noise_spec, site_of
from laboratory.isu.truth import calibration_truth
from procedures.isu.computations import calibration_data
from procedures.isu.day import measure_day
from procedures.isu.plan import DayPlan
from procedures.journal import Journal
from procedures.runner import Run
from station.config.isu import StationConfig, load_config
from station.config.plan import PlanSettings
from station.racks.isu import SimulatedRack, open_isu_drivers

POSITION_CHARTS = ("II-6", "II-11", "II-12", "II-13", "II-14")
# the manual's standard times whatever the lab's noise (no requirement can lengthen a gate)
MANUAL_DAY = DayPlan(requirements=PlanSettings(
    gyro_scale_factor=0.01, gyro_drift_deg_hr=10.0, accel_scale_factor_ppm=1e4,
    accel_bias_micro_g=1e4))


def random_lab(seed: int) -> StationConfig:
    """Random laboratory ``seed`` (laboratory/isu/random_lab.py) as this module drew it
    before the merge: the default pier and spin-axis rotations (with the pier at 0.3-3x,
    accel2 A.B3's fit gain falls to 1.27 in lab 102, pier 2.68: the named gains are the
    default pier's); ``calibration_day`` runs the manual's times, so no ``[plan]``."""
    return random_station(seed, reachable=False, extras=False)


def calibration_day(cfg: StationConfig, charts: tuple[str, ...] = POSITION_CHARTS,
                    plan: DayPlan | None = None) -> tuple[dict, dict, dict, dict]:
    """(CalibrationData as JSON, NoiseSpec as JSON, truth, the II-7 speed series) of the
    lab's ``charts`` (default the position charts only) under ``plan`` (default DayPlan())."""
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            run = Run(st.clock, Journal(Path(tmp) / "journal.jsonl"))
            plan, site, noise = plan or MANUAL_DAY, site_of(cfg), noise_spec(cfg)
            data = measure_day(st, run, plan, site, cfg.isu.accels[0].f0_hz,
                               only=charts, noise=noise)
            cd = calibration_data(data, plan, site)
        truth = {f"{i}|{p}": v for (i, p), v in calibration_truth(rack.world).items()}
        series = {str(k): v for k, v in data.nonlinearity.items()}
        return cd.model_dump(mode="json"), noise.model_dump(mode="json"), truth, series
    finally:
        st.close()
        rack.close()


def _signed(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi) * rng.choice([-1.0, 1.0]))


def steep_station(seed: int) -> StationConfig:
    """Random laboratory ``seed`` with every gyro's B at 30-100 deg/hr/g and every gyro and
    accelerometer axis 300-600 arcsec off nominal, the spin axes turned as far: admissible
    (sim/isu/params.py), and where Chart III-9's a.G = a.A is off by 0.1-0.3 deg/hr."""
    rng = np.random.default_rng(seed)
    doc = random_station(seed, reachable=False).model_dump(mode="json")
    for g in doc["isu"]["gyros"]:
        for name in ("B_I_deg_hr_g", "B_O_deg_hr_g", "B_S_deg_hr_g"):
            g[name] = _signed(rng, 30.0, 100.0)
        g["misalignment_arcsec"] = [_signed(rng, 300.0, 600.0) for _ in range(2)]
        g["spin_axis_rotation_arcsec"] = _signed(rng, 300.0, 600.0)
    for a in doc["isu"]["accels"]:
        a["misalignment_arcsec"] = [_signed(rng, 300.0, 600.0) for _ in range(2)]
    return load_config(seed=seed, overrides=doc)
