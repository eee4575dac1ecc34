"""What the alignment check-sheets share: the table at position 0, the autocollimators, the
experiment's Chart I-8 parameters, and the outcome of one alignment."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from procedures.isu import plausibility as pl
from procedures.isu import survey_math as sm
from procedures.isu.alignment import error_model as em
from procedures.isu.alignment.estimation import LevelParams
from procedures.isu.alignment.preprocess import Constants
from procedures.isu.alignment.results_sheet import AlignmentResults, AlignPlan
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.common import set_position
from procedures.isu.readings import read_levels, read_mirror, resolvers
from procedures.isu.sheets import CalibrationResults, SurveyResults
from procedures.isu.site import Site
from procedures.isu.system_survey import NOMINAL_AIM_DEG, POSITION0_DEG, acquire
from procedures.isu.turn_on import oscillator_periods
from procedures.medians import median
from procedures.runner import Run
from station.errors import CheckFailed

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

AC_NOISE_FLOOR_ARCSEC = 1e-3


@dataclass
class Outcome:
    """One alignment: its T, the time it refers to, its predicted error and physical limit."""

    method: str
    estimator: str
    K: int
    dt: float
    t: np.ndarray
    t_ref: float
    predicted_sigma_arcsec: list[float]  # about east, north, up
    physical_limit_arcsec: list[float]
    sheet: AlignmentResults
    detail: dict = field(default_factory=dict)


def canonical_estimator(method: str, estimator: str) -> str:
    """The technique actually run: level has no Earth rate, so its hybrid is the posterior
    mean; the gyrocompass's posterior mean is defined for g only (Chart III-10), with the
    simple average for the Earth rate, which is the hybrid. Mirror alignment averages."""
    if estimator not in ("average", "posterior", "hybrid"):
        raise ValueError(f"unknown estimator {estimator!r}: average, posterior or hybrid")
    if method == "mirror":
        return "average"
    if method == "level":
        return "posterior" if estimator == "hybrid" else estimator
    if method == "gyrocompass":
        return "hybrid" if estimator == "posterior" else estimator
    raise ValueError(f"unknown alignment method {method!r}: mirror, level or gyrocompass")


def require_turn_on(run: Run) -> dict:
    done = run.check_sheets.get("I-1")
    if done is None or not done.steps or not all(r.done for r in done.steps):
        raise CheckFailed("turn-on (Chart I-1) has not been completed in this run")
    return {"turn_on_completed_at_s": done.steps[-1].t_sim}


def set_position0(st: IsuDrivers, noise: NoiseSpec | None = None) -> dict:
    """Position 0 (the survey's) with bubble-level corrections on phi1 and phi3."""
    ps = set_position(st, *POSITION0_DEG, level=True, noise=noise)
    lev = ps.reading()
    return {"commanded_deg": list(ps.phi), "level_arcsec": list(ps.level_arcsec or (0, 0)),
            "level_check_arcsec": lev["level_check_arcsec"],
            **({"relevelled": lev["relevelled"]} if "relevelled" in lev else {}),
            "resolvers_deg": list(resolvers(st)), "t_s": st.clock.now()}


def table_record(st: IsuDrivers) -> tuple[tuple[float, float, float, float], tuple[float, float]]:
    """Resolver readouts and bubble levels (range-checked) for the Alignment Results Sheet."""
    pos = resolvers(st)
    lev = read_levels(st)
    return tuple(float(x) for x in pos), tuple(float(x) for x in lev)  # type: ignore[return-value]


def mirror_aims(survey: SurveyResults | None) -> dict[int, tuple[float, float]]:
    if survey is None:
        return dict(NOMINAL_AIM_DEG)
    a1, t1, a2, t2 = survey.autocollimator_deg
    return {1: (a1, t1), 2: (a2, t2)}


def acquire_mirrors(st: IsuDrivers, ks: Sequence[int], survey: SurveyResults | None) -> dict:
    aims = mirror_aims(survey)
    return {str(k): acquire(st.autocollimators[k], k, *aims[k]) for k in ks}


def read_autocollimators(st: IsuDrivers, ks: Sequence[int], n: int, survey: SurveyResults | None,
                         noise: NoiseSpec | None = None) -> dict:
    """``n`` readings of each autocollimator in ``ks``, alternating; means, times, spread.

    Each reading must lie in the instrument's range and agree with its repetitions
    (``plausibility.AgreeingReadings``: an outlier is read again, bounded and recorded in
    the enclosing ``rereads()`` block; the step stops naming the autocollimator otherwise).
    """
    noise = noise or NoiseSpec.model_validate({})
    aims = mirror_aims(survey)
    times: dict[int, list[float]] = {k: [] for k in ks}

    def read(k: int, i: int | None = None) -> list[float]:
        az, zen = read_mirror(st, k)
        az0 = aims[k][0]
        t = st.clock.now()
        if i is None:
            times[k].append(t)
        else:
            times[k][i] = t
        return [az0 + ((az - az0 + 180.0) % 360.0 - 180.0), zen]

    got = {k: pl.AgreeingReadings(st.autocollimators[k], f"mirror {k} azimuth and zenith",
                                  0.0, partial(read, k)) for k in ks}
    for _ in range(n):
        for k in ks:
            got[k].add(read(k))
    out = {}
    for k, g in got.items():
        zen = float(median([v[1] for v in g.values]))
        g.sigma = pl.autocollimator_sigma_deg(noise, times[k], zen)
        a = g.settle()
        out[k] = {
            "azimuth_deg": float(a[:, 0].mean()),
            "zenith_deg": float(a[:, 1].mean()),
            "times_s": list(times[k]),
            "spread_arcsec": ([float(x) for x in a[:, :2].std(axis=0, ddof=1) * 3600.0]
                              if n > 1 else [0.0, 0.0]),
        }
    return out


def calibration_constants(calib: CalibrationResults, gyros: bool) -> Constants:
    return Constants.from_sheet(calib, gyros)


def prior_t1(survey: SurveyResults | None) -> np.ndarray:
    """Nominal T (T^EB) at position 0 for Chart I-8: T^BI of the survey and the nominal
    position-0 angles through Chart I-4 (I-3.1, way 2); the identity mounting without it."""
    t_bi = np.eye(3) if survey is None else np.asarray(survey.t_bi, dtype=float)
    t_be = t_bi @ sm.t_ie(POSITION0_DEG)
    u, _, vt = np.linalg.svd(t_be.T)
    return u @ vt  # re-orthonormalised (the survey's T^BI is orthogonal to round-off)


def survey_g(survey: SurveyResults | None) -> float:
    return 1.0 if survey is None else float(survey.g)


def site_rates(survey: SurveyResults | None, site: Site | None) -> tuple[float, float]:
    """(omega^E sin lambda, omega^E cos lambda) in deg/hr: north and vertical components,
    as the survey recorded them (Chart I-2 step 3), else the site's."""
    if survey is not None:
        return survey.omega_sin_lambda_deg_hr, survey.omega_cos_lambda_deg_hr
    if site is None:
        raise ValueError("the gyrocompass alignment needs the Earth rate: give the survey "
                         "(Chart I-3) or the site")
    return site.omega_sin_lambda, site.omega_cos_lambda


def experiment_params(plan: AlignPlan, noise: NoiseSpec, survey: SurveyResults | None,
                      constants: Constants, K: int, dt: float,
                      t1: np.ndarray | None = None) -> LevelParams:
    """The Chart I-8 parameters this experiment specifies for a record of K x dt.

    ``t1``: the nominal attitude the plan's way of I-3.1 gave (None: the resolvers', way 2)."""
    d1 = float(np.mean(constants.vector("accel", "D1")))
    return em.level_params(
        noise, dt, K, t1=prior_t1(survey) if t1 is None else t1, g_tilde_g=survey_g(survey),
        sigma_g_g=plan.sigma_g_g, sigma_theta_arcsec=plan.sigma_theta_arcsec,
        eps_t=plan.eps_t_s, d1_pps_per_g=d1,
    )


def ac_sigma_arcsec(noise: NoiseSpec, n: int) -> float:
    return max(noise.autocollimator_arcsec, AC_NOISE_FLOOR_ARCSEC) / math.sqrt(n)


def ieu_period_ticks(run: Run, period_s: float) -> tuple[int, float]:
    """IEU sample period in S2^T pulses for ``period_s`` (and S2^T, as turn-on recorded it:
    Chart I-1 step 3, read twice there)."""
    _, s2 = oscillator_periods(run)
    return int(round(period_s / s2)), s2


OSCILLATOR_STATES = ("LOCKED", "UNLOCKED")
STRING_HZ = (1e4, 3e4)  # the strings count near 20 kHz (their data sheet)


def check_ieu_lines(st: IsuDrivers, period_ticks: int, gyros: bool, s2: float) -> dict:
    """Verify the oscillator and instrument lines reach the IEU: two samples whose timer
    counts the period and whose strings count near the basic frequency (Chart III-4 step 2,
    Chart III-8 step 2). ``s2``: S2^T as turn-on recorded it."""
    status = pl.read_word(st.oscillator, st.oscillator.status, OSCILLATOR_STATES, "status")
    if status != "LOCKED":
        raise pl.Implausible(pl.source_of(st.oscillator), f"status {status!r}, not LOCKED")
    ieu = st.ieu.status()
    if int(ieu.get("ErrorCode", 0)) != 0:
        raise pl.Implausible(pl.source_of(st.ieu), f"reports error code {ieu['ErrorCode']}")
    st.ieu.start(period_ticks, recover=True)
    try:
        samples = [st.ieu.next_sample() for _ in range(2)]
    finally:
        st.ieu.stop()
    per_s = period_ticks * s2
    last = samples[-1]
    if last.timer != period_ticks:
        raise pl.Implausible(pl.source_of(st.ieu), f"timer counted {last.timer}, not "
                             f"{period_ticks}: check the master oscillator's S2^T line")
    rates = [c / per_s for c in last.accel]
    dead = [n for n, r in zip(("A1S1", "A1S2", "A2S1", "A2S2", "A3S1", "A3S2"), rates,
                              strict=True) if not STRING_HZ[0] < r < STRING_HZ[1]]
    if dead:
        raise pl.Implausible(pl.source_of(st.ieu), f"string line(s) {dead} not counting near "
                             f"20 kHz at the IEU: {[round(r) for r in rates]} Hz")
    out = {"oscillator": status, "ieu_error_code": int(ieu.get("ErrorCode", 0)),
           "string_hz": [round(r, 1) for r in rates], "timer": last.timer}
    if gyros:
        out["gyro_pulses_per_s"] = [g / per_s for g in last.gyro]
    return out
