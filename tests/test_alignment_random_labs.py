"""The level and gyrocompass alignments' predicted sigmas in random admissible laboratories
(issue 19; laboratory/isu/random_lab.py).

Each laboratory runs turn-on and the survey (Charts I-1, I-2), then the level (Chart III-5..
III-7) and gyrocompass (III-9..III-11) alignments by the simple average, short records. The
calibration is a drawn one instead of a day: the true constants (as counted against the
laboratory's master oscillator, ``on_lab_clock``) plus an error drawn from
the closed forms' predicted covariance of a standard day (procedures.isu.accuracy.Predictor,
the default laboratory's, Charts II-18..II-24), with that covariance's sigmas and
correlation on the sheet (Chart II-15 step 8). So the test holds the alignments' own models:
the sheet's errors carried through with their correlation, plus the alignment's noise, pier
and quantization terms, against the simulator's true attitude. Every axis within 4
predicted sigma, and the rms of error/sigma over the set within its chi-square 99.9 %
interval.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from random_labs import steep_station
from scipy.stats import chi2

from laboratory.isu.align import alignment_entries
from laboratory.isu.random_lab import random_station
from laboratory.isu.spec import noise_spec, site_of
from laboratory.isu.truth import calibration_truth
from procedures.isu.accuracy import Predictor
from procedures.isu.alignment.options import AlignmentOptions
from procedures.isu.alignment.run import run_alignments
from procedures.isu.calibration.compute import correlation
from procedures.isu.plan import DayPlan
from procedures.isu.settings import manual_times, planning_lab
from procedures.isu.sheets import CalibrationResults, ResultRow
from procedures.isu.system_survey import system_survey
from procedures.isu.turn_on import turn_on
from procedures.journal import Journal
from procedures.runner import Run
from station.config.alignment import AlignPlan
from station.config.isu import StationConfig, load_config
from station.racks.isu import SimulatedRack, open_isu_drivers

SEEDS = (201, 202, 203, 204)
SHORT = AlignPlan(level_K=20, gyro_K=24)  # 40 s level, 120 s gyrocompass records


@pytest.fixture(scope="module")
def standard_covariance() -> tuple[list[tuple[str, str]], np.ndarray]:
    """The closed forms' predicted covariance of a standard day in the default laboratory."""
    cfg, plan = load_config(), DayPlan()
    lab = planning_lab(plan, site_of(cfg), noise_spec(cfg), f0=cfg.isu.accels[0].f0_hz)
    pred = Predictor(lab, manual_times(plan))
    return pred.rows, pred.covariance(manual_times(plan))


def drawn_calibration(truth: dict[tuple[str, str], float],
                      cov: tuple[list[tuple[str, str]], np.ndarray],
                      rng: np.random.Generator) -> CalibrationResults:
    """A Calibration Results Sheet: the truth plus an error drawn from ``cov``, its sigmas
    and correlation; the special experiments' rows (Q_II, Q_IS, J) exact."""
    rows, c = cov
    err = dict(zip(rows, rng.multivariate_normal(np.zeros(len(rows)), c), strict=True))
    sig = dict(zip(rows, np.sqrt(np.diag(c)), strict=True))
    sheet = [ResultRow(instrument=i, parameter=p, units="", estimate=v + err.get((i, p), 0.0),
                       sigma=sig.get((i, p)), positions="drawn")
             for (i, p), v in truth.items()]
    return CalibrationResults(rows=sheet, positions_used=[], correlation=correlation(rows, c))


def on_lab_clock(truth: dict[tuple[str, str], float], cfg: StationConfig
                 ) -> dict[tuple[str, str], float]:
    """The constants as a day counted against this laboratory's master oscillator would
    find them, offset e from nominal: the accelerometers' D1 (pulses per counted second)
    over 1 + e, the gyros' R under 1 - e (the rest by e times a fraction of a sigma). The
    IEU's timer runs on the same oscillator, so the alignments see the same e."""
    e = cfg.oscillator.frequency_error
    out = dict(truth)
    for (inst, p), v in truth.items():
        if p == "D1":
            out[(inst, p)] = v / (1.0 + e)
        elif p == "R":
            out[(inst, p)] = v * (1.0 - e)
    return out


def alignment_z(seed: int, cov: tuple[list[tuple[str, str]], np.ndarray],
                cfg: StationConfig | None = None) -> list[dict]:
    """Laboratory ``seed``'s (or ``cfg``'s) level and gyrocompass alignments (results.json
    entries)."""
    cfg = cfg or random_station(seed, reachable=False)
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    try:
        with tempfile.TemporaryDirectory() as d:
            run = Run(st.clock, Journal(Path(d) / "j.jsonl"))
            turn_on(st, run, 60.0)
            survey = system_survey(st, run, site_of(cfg), noise=noise_spec(cfg))
            calib = drawn_calibration(on_lab_clock(calibration_truth(rack.world), cfg), cov,
                                      np.random.default_rng(seed))
            out = run_alignments(st, run, AlignmentOptions(
                noise_spec(cfg), calib, survey, site_of(cfg), SHORT,
                estimators={"level": ("average",), "gyrocompass": ("average",)}))
            return alignment_entries(out, rack.world)
    finally:
        st.close()
        rack.close()


def test_alignment_axes_within_their_sigma_in_random_labs(standard_covariance) -> None:
    z: list[float] = []
    for seed in SEEDS:
        for e in alignment_z(seed, standard_covariance):
            assert [x for x in e["error_over_sigma"] if abs(x) >= 4] == [], (seed, e)
            z += e["error_over_sigma"]
    n = len(z)
    assert n == 6 * len(SEEDS)
    rms = math.sqrt(sum(x * x for x in z) / n)
    lo, hi = (math.sqrt(chi2.ppf(q, n) / n) for q in (0.0005, 0.9995))
    assert lo < rms < hi, (rms, lo, hi, z)


@pytest.mark.parametrize("seed", (211, 212))
def test_gyrocompass_on_steep_g_sensitivity_and_misaligned_axes(standard_covariance,
                                                                 seed: int) -> None:
    """The gyros' g terms are taken on the calibration's own axes (preprocess.gyro_integrals),
    and the record's truth is read on them (laboratory.isu.truth): the alignments stay within
    4 predicted sigma and pass their checks of |omega| and the colatitude (Chart III-8 step
    10), which the chart's nominal-axis form failed by 7 sigma at the bounds."""
    entries = alignment_z(seed, standard_covariance, steep_station(seed))
    assert [e["method"] for e in entries] == ["level", "gyrocompass"]
    for e in entries:
        assert [x for x in e["error_over_sigma"] if abs(x) >= 4] == [], (seed, e)
