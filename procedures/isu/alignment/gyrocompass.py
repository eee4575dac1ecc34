"""Gyrocompass alignment (Chart III-8, steps 1-10; computations Charts III-9..III-11).

Gyros and accelerometers through the IEU for K intervals of Delta t; every term of the gyro
and accelerometer models is removed with the calibration constants (Chart III-9); g and the
Earth rate in body axes are estimated (Chart III-10: simple average of both, or the hybrid:
the posterior mean of a level tape for g and the simple average for the Earth rate); Chart
III-11 gives T. T refers to t* = the end of the data plus eps_t.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from procedures.isu import plausibility as pl
from procedures.isu.alignment import checks as ck
from procedures.isu.alignment import error_model as em
from procedures.isu.alignment import estimation as es
from procedures.isu.alignment.align_math import ARCSEC, gyrocompass_matrix
from procedures.isu.alignment.common import (
    Outcome,
    calibration_constants,
    check_ieu_lines,
    experiment_params,
    ieu_period_ticks,
    prior_t1,
    require_turn_on,
    set_position0,
    site_rates,
    survey_g,
    table_record,
)
from procedures.isu.alignment.level import ACCEL_KEYS, BIAS_KEYS, check_record, x_of
from procedures.isu.alignment.options import AlignmentOptions
from procedures.isu.alignment.parameter_sheet import Tape, check_tape
from procedures.isu.alignment.preprocess import (
    GYRO_PARAMS,
    Constants,
    accel_integrals,
    gyro_integrals,
)
from procedures.isu.alignment.preprocess import string_differences as p_of
from procedures.isu.alignment.reduced import (
    ALL,
    Instruments,
    check_gyrocompass_set,
    gyrocompass_attitude,
)
from procedures.isu.alignment.results_sheet import AlignmentResults, AlignPlan
from procedures.isu.alignment.sampling import IeuRecord, collect_checked
from procedures.isu.sheets import SurveyResults, scale_factor_arcsec
from procedures.runner import Run
from station.errors import CheckFailed

if TYPE_CHECKING:
    from procedures.isu.calibration.noise_spec import NoiseSpec
    from station.drivers.isu import IsuDrivers

CHART = "III-8"
TITLE = "Gyrocompass alignment"
GYRO_KEYS = [(f"gyro{k}", p) for k in (1, 2, 3) for p in GYRO_PARAMS]


def gyro_x(record: IeuRecord, c: Constants, inst: Instruments | None = None,
           g_survey: float | None = None) -> np.ndarray:
    """Gyro part of X (Chart III-10), axis by axis (3K), arcsec. With an accelerometer
    absent (III-3.2), the gyros' g-sensitive terms take its component of g from the nominal
    attitude and the surveyed |g|."""
    _, _, u = accel_integrals(p_of(record.strings), record.dt, c)
    return _gyro_x(record, c, u, inst, g_survey)


def _gyro_x(record: IeuRecord, c: Constants, u: np.ndarray, inst: Instruments | None,
            g_survey: float | None) -> np.ndarray:
    """``gyro_x`` from the accelerometers' integrals ``u`` already at hand."""
    if inst is not None and inst.accels != ALL and inst.t_prior is not None and g_survey:
        for k in set(ALL) - set(inst.accels):
            u[:, k - 1] = g_survey * float(np.asarray(inst.t_prior)[0, k - 1])
    return gyro_integrals(record.gyro, record.dt, u, c).T.reshape(-1)


def gyro_t(g_b: np.ndarray, w_b: np.ndarray, opts: dict[str, float],
           inst: Instruments | None = None) -> np.ndarray:
    """T by Chart III-11, or from a reduced instrument set (III-3.2, ``reduced``)."""
    if inst is not None and inst.reduced:
        return gyrocompass_attitude(g_b, w_b, inst, opts["g_survey"], opts["w_survey"],
                                    opts["colatitude_deg"])
    return gyrocompass_matrix(g_b, w_b, **opts)


def matrices(estimator: str, K: int, dt: float, tape: Tape | None
             ) -> tuple[np.ndarray, np.ndarray]:
    """(M, b), 6 x 6K, acting on (accelerometers in m/s^2 s, gyros in arcsec)."""
    if estimator == "average":
        return es.simple_average(K, dt, n_axes=6)
    if tape is None:
        raise ValueError("the hybrid technique needs a level tape (Chart I-7)")
    M, b, _ = tape.arrays()
    return es.hybrid_gyrocompass(M, b, K, dt)


def record_x(record: IeuRecord, c: Constants, inst: Instruments | None,
             g_survey: float | None) -> np.ndarray:
    """X of Chart III-10 (accelerometers in m/s^2 s, gyros in arcsec; 6K) from the record
    with the constants ``c``: what every technique's estimate (M X + b) starts from.
    Read-only: the techniques of one record share it (``gyrocompass_procedure``)."""
    int_b, _, u = accel_integrals(p_of(record.strings), record.dt, c)
    x = np.concatenate((x_of(int_b), _gyro_x(record, c, u, inst, g_survey)))
    x.setflags(write=False)
    return x


def gyro_solution(record: IeuRecord, c: Constants, M: np.ndarray, b: np.ndarray,
                  opts: dict[str, float], inst: Instruments | None = None,
                  x: Callable[[Constants], np.ndarray] | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T, g_B in g, omega_B in deg/hr); ``inst``: the instruments used (all when None).
    ``x``: ``record_x`` of this record, instruments and options, held by the constants
    (the techniques of one record share it)."""
    xc = (x(c) if x is not None else record_x(record, c, inst, opts.get("g_survey")))
    est = M @ xc + b
    g_b, w_b = est[:3] / es.G0, est[3:]
    return gyro_t(g_b, w_b, opts, inst), g_b, w_b


def gyro_error_model(record: IeuRecord, c: Constants, M: np.ndarray, b: np.ndarray,
                     opts: dict[str, float], params: es.LevelParams, noise: NoiseSpec,
                     w_horizontal: float, inst: Instruments | None = None,
                     x: Callable[[Constants], np.ndarray] | None = None) -> dict:
    """Predicted phi covariance (U, E, N) and the physical limits (Chart III-11). ``x``:
    the record's X by the constants, as ``gyro_solution`` takes it."""
    t0, g_b, w_b = gyro_solution(record, c, M, b, opts, inst, x)
    # the three perturbation passes below (T, |omega|, colatitude) share each solution
    solution = em.memoized(lambda cc: gyro_solution(record, cc, M, b, opts, inst, x))

    def solve(cc: Constants) -> np.ndarray:
        return solution(cc)[0]

    cal = em.calibration_terms(c, solve, ACCEL_KEYS + GYRO_KEYS)
    cov_cal = em.correlated_cov(cal, c)
    cov_bias = em.correlated_cov(cal, c, lambda k: k in BIAS_KEYS)
    cov_gyro_cal = em.correlated_cov(cal, c, lambda k: k[0].startswith("gyro"))
    # g: the estimator's error covariance against g at t* (simple average or posterior)
    cov_g = es.error_covariance(M[:3, : 3 * params.K], b[:3], params) / es.G0**2
    j_g = em.jacobian(em.phi_of(t0, lambda g: gyro_t(g, w_b, opts, inst)), g_b, 1e-7)
    # omega: per-gyro noise averaged over the record, and the pier's mean tilt rate
    span = float(np.sum(record.dt))
    dphi = c.vector("gyro", "DeltaPhi")
    per = [em.gyro_rate_variance(noise, span, scale_factor_arcsec(float(d))) for d in dphi]
    cov_w = np.diag([sum(p.values()) for p in per])
    tilt = np.zeros((3, 3))
    tilt[1:, 1:] = em.tilt_rate_cov(noise, span)
    cov_w = cov_w + t0.T @ tilt @ t0  # earth (U, E, N) to body: T^T C T
    j_w = em.jacobian(em.phi_of(t0, lambda w: gyro_t(g_b, w, opts, inst)), w_b, 1e-4)
    cov = cov_cal + j_g @ cov_g @ j_g.T + j_w @ cov_w @ j_w.T
    bias = em.as_enu_arcsec(cov_bias)
    # azimuth limit: residual gyro bias (calibration) and the gyro's noise (N / sqrt(T))
    # and random drift, over the horizontal Earth rate omega^E cos(latitude)
    noise_rate = math.sqrt(noise.gyro_arw_deg_rt_hr**2 / (span / 3600.0)
                           + noise.gyro_drift_sigma_deg_hr**2)
    az_lim = math.sqrt(cov_gyro_cal[0, 0] / ARCSEC**2
                       + (noise_rate / w_horizontal / ARCSEC) ** 2)
    parts = {"calibration_accel": em.as_enu_arcsec(cov_cal - cov_gyro_cal),
             "calibration_gyro": em.as_enu_arcsec(cov_gyro_cal),
             "estimator_g": em.as_enu_arcsec(j_g @ cov_g @ j_g.T),
             "gyro_noise_and_tilt_rate": em.as_enu_arcsec(j_w @ cov_w @ j_w.T),
             "gyro_rate_sigma_deg_hr": {k: math.sqrt(per[0][k]) for k in per[0]}}
    # |omega| and the angle between omega and the vertical: calibration and gyro noise
    def scalars(g: np.ndarray, w: np.ndarray) -> np.ndarray:
        return np.array([float(np.linalg.norm(w)), ck.angle_deg(w, g)])

    cal_w = ck.cal_sigma(c, lambda cc: float(np.linalg.norm(solution(cc)[2])))
    cal_col = ck.cal_sigma(c, lambda cc: ck.angle_deg(*solution(cc)[2:0:-1]))
    j_sw = em.jacobian(lambda w: scalars(g_b, w), w_b, 1e-4)
    j_sg = em.jacobian(lambda g: scalars(g, w_b), g_b, 1e-7)
    cov_s = j_sw @ cov_w @ j_sw.T + j_sg @ cov_g @ j_sg.T
    w_sigma = math.hypot(cal_w, math.sqrt(max(float(cov_s[0, 0]), 0.0)))
    col_sigma = math.hypot(cal_col, math.sqrt(max(float(cov_s[1, 1]), 0.0)))
    return {"t": t0, "g_b": g_b, "w_b": w_b, "cov": cov, "predicted": em.as_enu_arcsec(cov),
            "limit": [bias[0], bias[1], az_lim], "parts": parts,
            "w_sigma": w_sigma, "colatitude_sigma": col_sigma}


GYRO_BLAME = ("the gyro or accelerometer data from the IEU (ieu) or the calibration constants "
              "(counters, Charts II-6..II-14) are wrong")


def gyro_checks(e: str, model: dict, survey: SurveyResults | None, w_north: float,
                w_up: float, reference: tuple | None) -> dict:
    """|g|, |omega|, the colatitude and T against what the survey and site know."""
    src = f"gyrocompass alignment ({e})"
    w_b, g_b = model["w_b"], model["g_b"]
    out = {"|omega|": ck.check(src, "|omega| measured", float(np.linalg.norm(w_b)),
                               math.hypot(w_north, w_up), model["w_sigma"], "deg/hr",
                               GYRO_BLAME),
           "colatitude": ck.check(src, "angle between omega and the vertical",
                                  ck.angle_deg(w_b, g_b),
                                  math.degrees(math.atan2(w_north, w_up)),
                                  model["colatitude_sigma"], "deg", GYRO_BLAME)}
    if reference is not None:
        t_ref, s_ref, name, motion = reference
        out |= ck.check_attitude(src, model["t"], model["predicted"], t_ref, s_ref, name,
                                 GYRO_BLAME, motion)
    return out


def check_instruments(plan: AlignPlan, inst: Instruments, ests: tuple[str, ...],
                      opts: dict[str, float]) -> None:
    """Refuse (CheckFailed) a gyrocompass alignment the plan's instruments cannot make."""
    why = plan.reduced_refusal("gyrocompass")
    if why is not None:
        raise CheckFailed(why)
    if inst.reduced:
        check_gyrocompass_set(inst, opts["colatitude_deg"])
        if any(e != "average" for e in ests):
            raise CheckFailed("accels/gyros: the hybrid technique's tape is made for three "
                              "accelerometers (Chart I-9): use the simple average")


def gyrocompass_procedure(st: IsuDrivers, run: Run, options: AlignmentOptions,
                          mirror: Outcome | None = None, quick: bool = False
                          ) -> list[Outcome]:
    """Tick Chart III-8; one Outcome (and Alignment Results Sheet) per technique that
    ``options`` asks for the gyrocompass method (the simple average when it names none).

    ``options.tapes["gyrocompass"]``: the level tape for this experiment's K and Delta t
    (hybrid). ``mirror``: the mirror alignment of this run, which T is checked against at
    step 10 (else the survey's prediction, if the survey was made in this run); |omega| and
    the colatitude are checked against the survey's Earth rate (the site's without one),
    |g| against the survey. ``quick``: the quick alignment of I-3.1 way 3 (simple average
    over ``plan.quick_K`` intervals; sheet ``III-8-quick``), which gives the nominal T1 of
    Chart I-8.
    """
    noise, calib, survey, plan = options.noise, options.calib, options.survey, options.plan
    calibration_id = options.calibration_id
    ests = ("average",) if quick else (options.techniques("gyrocompass") or ("average",))
    K, dt = plan.quick_K if quick else plan.gyro_K, plan.gyro_dt_s
    tapes = {e: t for e in ests if (t := options.tape_for("gyrocompass", e)) is not None}
    w_north, w_up = site_rates(survey, options.site)
    opts: dict[str, float] = {}
    if plan.known_colatitude:
        opts["colatitude_deg"] = math.degrees(math.atan2(w_north, w_up))
    if plan.surveyed_g:
        opts["g_survey"] = survey_g(survey)
    if plan.surveyed_earth_rate:
        opts["w_survey"] = math.hypot(w_north, w_up)
    chart, title, suffix = ((f"{CHART}-quick", f"Quick {TITLE.lower()} (I-3.1, way 3)",
                             "_quick") if quick else (CHART, TITLE, ""))
    t_prior = options.nominal_t1()
    inst = Instruments(plan.accels, plan.gyros, prior_t1(survey) if t_prior is None else t_prior)
    with run.sheet(chart, title) as sheet:
        with sheet.step("1", "Verify turn-on procedures and Alignment Results Sheet are "
                        "completed") as s:
            s.reading = require_turn_on(run) | {"K": K, "dt_s": dt, "estimators": list(ests),
                                                "calibration_id": calibration_id,
                                                "options": opts,
                                                "instruments": {"accels": list(plan.accels),
                                                                "gyros": list(plan.gyros)}}
            check_instruments(plan, inst, ests, opts)
        with sheet.step("1a", "(project addition) Set position 0 with bubble-level "
                        "corrections on phi1 and phi3") as s:
            position0 = s.reading = set_position0(st, noise)
        period, s2 = ieu_period_ticks(run, plan.gyro_period_s)
        with sheet.step("2", "Verify master oscillator, gyros and accelerometers are "
                        "connected to the IEU") as s, pl.rereads() as rr:
            s.reading = pl.with_rereads(check_ieu_lines(st, period, True, s2), rr)
        with sheet.step("3", "Set sampling rate on IEU panel") as s:
            spi = int(round(dt / (period * s2)))
            s.reading = {"period_ticks": period, "period_s": period * s2,
                         "samples_per_interval": spi}
        sheet.done("4", "Load gyrocompass program",
                   {"program": "procedures.isu.alignment.gyrocompass",
                    "charts": ["III-9", "III-10", "III-11"]})
        with sheet.step("5", "Load calibration constants from current Calibration Results "
                        "Sheet") as s:
            c = calibration_constants(calib, gyros=True)
            s.reading = {"calibration_id": calibration_id, "constants": len(c.values)}
        sheet.done("6", "Enter number of samples K and inter-sample time Delta t",
                   {"K": K, "dt_s": dt})
        params = experiment_params(plan, noise, survey, c, K, dt, options.nominal_t1())
        with sheet.step("7", "Enter parameters from parameter evaluation program for "
                        "selected K and Delta t") as s:
            used = {}
            for e in ests:
                if e == "average":
                    continue
                tape = tapes.get(e)
                if tape is None:
                    raise CheckFailed(f"no level tape for the {e} technique: run Chart I-7")
                check_tape(tape, params)
                used[e] = tape.sheet.reel_id
            s.reading = {"tapes": used} if used else {"tapes": None,
                                                       "note": "simple average: not required"}
        with sheet.step("8", "Initiate alignment: IEU data, preprocessing (Chart III-9), "
                        "estimation (Chart III-10), T (Chart III-11)") as s:
            record = collect_checked(st, period, spi, K, plan.recover_lost_samples, s2, noise,
                                     plan.ieu_retakes)
            check_record(record, K, dt)
            mats = {e: matrices(e, K, dt, tapes.get(e)) for e in ests}
            # X by the constants, shared by the techniques and their error models' passes
            # (one record: the day's two techniques perturb the same constants, issue 17)
            xs = em.memoized(lambda cc: record_x(record, cc, inst, opts.get("g_survey")))
            sols = {e: gyro_solution(record, c, M, b, opts, inst, xs)
                    for e, (M, b) in mats.items()}
            s.reading = record.summary() | {
                e: {"g_body_g": sol[1].tolist(), "omega_body_deg_hr": sol[2].tolist()}
                for e, sol in sols.items()}
        with sheet.step("9", "Enter test table bubble levels and resolver readouts") as s:
            pos, lev = table_record(st)
            s.reading = {"resolvers_deg": list(pos), "bubble_levels_arcsec": list(lev)}
        with sheet.step("10", "After computer output, enter T on the Alignment Results "
                        "Sheet") as s:
            t_ref = record.t_end + plan.eps_t_s
            reference = ck.attitude_reference(
                survey, survey is not None and run.sheets.get("survey_results") is survey,
                mirror, position0, noise, t_ref)
            out = []
            checked = {}
            for e, (M, b) in mats.items():
                model = gyro_error_model(record, c, M, b, opts, params, noise, w_north, inst,
                                         xs)
                checked[e] = gyro_checks(e, model, survey, w_north, w_up, reference)
                sheet_model = AlignmentResults(
                    procedure="gyrocompass", estimator=e, calibration_id=calibration_id,
                    filtering_parameter_id=tapes[e].sheet.reel_id if e in tapes else None,
                    dt_s=dt, K=K, table_position_deg=pos, bubble_levels_arcsec=lev,
                    t=model["t"].tolist(), t_ref_s=t_ref,
                    predicted_sigma_arcsec=tuple(model["predicted"]),
                    physical_limit_arcsec=tuple(model["limit"]),
                    options={k: float(v) for k, v in opts.items()},
                    notes=[f"IEU {record.K * spi} samples of {period} S2^T pulses; "
                           f"{len(record.recoveries)} recovered by RESEND",
                           "Q_IS term as Chart IV-2, (w.G)(w.S) (Chart III-9 prints (w.G)(a.S))"]
                    + ([f"{inst.describe()}: T fitted to their components with the "
                        "surveyed |g|, |omega^E| and colatitude (III-3.2)"]
                       if inst.reduced else []),
                )
                run.save_sheet(f"alignment_results_gyrocompass_{e}{suffix}", sheet_model)
                out.append(Outcome("gyrocompass", e, K, dt, model["t"], t_ref,
                                   model["predicted"], model["limit"], sheet_model,
                                   {"parts": model["parts"], "g_body_g": model["g_b"].tolist(),
                                    "omega_body_deg_hr": model["w_b"].tolist(),
                                    "recovered": record.recoveries,
                                    "ieu_samples": record.raw}))
            s.reading = {o.estimator: {"t": o.t.tolist(),
                                       "predicted_sigma_arcsec": o.predicted_sigma_arcsec,
                                       "checks": checked[o.estimator]}
                         for o in out}
    return out
