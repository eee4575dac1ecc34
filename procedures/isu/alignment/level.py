"""Level alignment (Chart III-4, steps 1-12; computations Charts III-5, III-6, III-7).

The accelerometers are read through the IEU for K intervals of Delta t (several IEU samples
each), preprocessed with the calibration constants (Chart III-5), and g in body axes is
estimated by the simple average or by the posterior mean of a tape (Chart III-6); with the
azimuth of mirror 1 from an autocollimator, Chart III-7 gives T. T refers to t* = the end
of the data plus eps_t (Chart I-9), for both estimators, so they can be compared.

Several techniques may process the same record (``estimators``); each gets its own
Alignment Results Sheet (``alignment_results_level_<estimator>``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from procedures.isu import plausibility as pl
from procedures.isu.alignment import checks as ck
from procedures.isu.alignment import error_model as em
from procedures.isu.alignment import estimation as es
from procedures.isu.alignment.align_math import level_matrix
from procedures.isu.alignment.common import (
    Outcome,
    ac_sigma_arcsec,
    acquire_mirrors,
    calibration_constants,
    check_ieu_lines,
    experiment_params,
    ieu_period_ticks,
    prior_t1,
    read_autocollimators,
    require_turn_on,
    set_position0,
    survey_g,
    table_record,
)
from procedures.isu.alignment.options import AlignmentOptions
from procedures.isu.alignment.parameter_sheet import Tape, check_tape
from procedures.isu.alignment.preprocess import ACCEL_PARAMS, Constants, accel_integrals
from procedures.isu.alignment.preprocess import string_differences as p_of
from procedures.isu.alignment.reduced import ALL, Instruments, check_level_set, complete_gravity
from procedures.isu.alignment.results_sheet import AlignmentResults, AlignPlan
from procedures.isu.alignment.sampling import IeuRecord, collect_checked
from procedures.isu.sheets import SurveyResults
from procedures.runner import Run
from station.errors import CheckFailed

if TYPE_CHECKING:
    from procedures.isu.calibration.noise_spec import NoiseSpec
    from station.drivers.isu import IsuDrivers

CHART = "III-4"
TITLE = "Level alignment"
ACCEL_KEYS = [(f"accel{k}", p) for k in (1, 2, 3) for p in ACCEL_PARAMS]
BIAS_KEYS = [(f"accel{k}", p) for k in (1, 2, 3) for p in ("D0", "A.B1", "A.B2", "A.B3")]


def estimator_matrices(estimator: str, K: int, dt: float, tape: Tape | None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """(M, b) acting on X in m/s^2 s (SI, as the tapes)."""
    if estimator == "average":
        return es.simple_average(K, dt)
    if tape is None:
        raise ValueError(f"the {estimator} technique needs a tape (Chart I-7)")
    M, b, _ = tape.arrays()
    return M, b


def accel_x(record: IeuRecord, c: Constants) -> np.ndarray:
    """X of Chart III-6 (axis by axis, 3K) in m/s^2 s."""
    int_b, _, _ = accel_integrals(p_of(record.strings), record.dt, c)
    return x_of(int_b)


def x_of(int_b: np.ndarray) -> np.ndarray:
    """X of Chart III-6 from the accelerometers' integrals (K x 3, g s)."""
    return int_b.T.reshape(-1) * es.G0


def check_record(record: IeuRecord, K: int, dt: float) -> None:
    if record.K != K or np.max(np.abs(record.dt - dt)) > 1e-9 * dt:
        raise CheckFailed(f"record of {record.K} intervals of {record.dt.min()}-"
                          f"{record.dt.max()} s, not K = {K} of {dt} s")


def level_t(g_b: np.ndarray, alpha1: float, theta1: float | None, g_survey: float | None,
            inst: Instruments | None = None) -> np.ndarray:
    """Chart III-7's T, with an absent accelerometer's component from |g| (III-2.2)."""
    if inst is not None and inst.accels != ALL and g_survey is not None:
        g_b = complete_gravity(g_b, inst, g_survey)
    return level_matrix(g_b, alpha1, theta1_deg=theta1, g_survey=g_survey)


def level_solution(record: IeuRecord, c: Constants, M: np.ndarray, b: np.ndarray, alpha1: float,
                   theta1: float | None, g_survey: float | None,
                   inst: Instruments | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(T, g_B in g) from a record, the constants and the estimator (Charts III-5..III-7);
    ``inst``: the instruments used (III-2.2), all three accelerometers when None."""
    g_b = (M @ accel_x(record, c) + b) / es.G0
    if inst is not None and inst.accels != ALL and g_survey is not None:
        g_b = complete_gravity(g_b, inst, g_survey)
    return level_t(g_b, alpha1, theta1, g_survey), g_b


def level_error_model(record: IeuRecord, c: Constants, M: np.ndarray, b: np.ndarray,
                      alpha1: float, theta1: float | None, g_survey: float | None,
                      params: es.LevelParams, noise: NoiseSpec, n_alpha: int,
                      inst: Instruments | None = None) -> dict:
    """Predicted phi covariance (U, E, N) of one level alignment and its physical limit."""
    t0, g_b = level_solution(record, c, M, b, alpha1, theta1, g_survey, inst)

    # the two perturbation passes (T, |g|) share each solution
    solution = em.memoized(lambda cc: level_solution(record, cc, M, b, alpha1, theta1,
                                                     g_survey, inst))

    def solve(cc: Constants) -> np.ndarray:
        return solution(cc)[0]

    cal = em.calibration_terms(c, solve, ACCEL_KEYS)
    cov_cal = em.correlated_cov(cal, c)
    cov_bias = em.correlated_cov(cal, c, lambda k: k in BIAS_KEYS)
    cov_g = es.error_covariance(M, b, params) / es.G0**2  # g^2, against g at t*
    j_g = em.jacobian(em.phi_of(t0, lambda g: level_t(g, alpha1, theta1, g_survey, inst)),
                      g_b, 1e-7)
    sa = ac_sigma_arcsec(noise, n_alpha) / 3600.0  # deg
    angles = np.array([alpha1, theta1 if theta1 is not None else 90.0])
    j_a = em.jacobian(em.phi_of(t0, lambda x: level_matrix(
        g_b, x[0], theta1_deg=None if theta1 is None else x[1], g_survey=g_survey)),
        angles, 1e-5)
    cov_ac = j_a @ np.diag([sa**2, sa**2]) @ j_a.T
    cov = cov_cal + j_g @ cov_g @ j_g.T + cov_ac
    bias = em.as_enu_arcsec(cov_bias)
    parts = {"calibration": em.as_enu_arcsec(cov_cal),
             "estimator": em.as_enu_arcsec(j_g @ cov_g @ j_g.T),
             "autocollimator": em.as_enu_arcsec(cov_ac)}
    # |g|: the calibration constants and the estimator's error along the vertical
    u = g_b / np.linalg.norm(g_b)
    g_cal = ck.cal_sigma(c, lambda cc: float(np.linalg.norm(solution(cc)[1])))
    g_sigma = math.hypot(g_cal, math.sqrt(max(float(u @ cov_g @ u), 0.0)))
    return {"t": t0, "g_b": g_b, "cov": cov, "predicted": em.as_enu_arcsec(cov),
            "limit": [bias[0], bias[1], ac_sigma_arcsec(noise, n_alpha)], "parts": parts,
            "g_sigma": g_sigma}


ACCEL_BLAME = ("the accelerometer data from the IEU (ieu) or the accelerometer constants "
               "(counters 1-6, Charts II-13, II-14) are wrong")


def level_checks(e: str, model: dict, survey: SurveyResults | None,
                 reference: tuple | None) -> dict:
    """|g| against the survey's g and T against the reference attitude (``checks``)."""
    src = f"level alignment ({e})"
    out = {}
    if survey is not None:
        out["|g|"] = ck.check(src, "|g| measured", float(np.linalg.norm(model["g_b"])),
                              float(survey.g), model["g_sigma"], "g", ACCEL_BLAME)
    if reference is not None:
        t_ref, s_ref, name, motion = reference
        out |= ck.check_attitude(src, model["t"], model["predicted"], t_ref, s_ref, name,
                                 ACCEL_BLAME + ", or the autocollimator's azimuth "
                                 "(autocollimator1)", motion)
    return out


def check_instruments(plan: AlignPlan, inst: Instruments, ests: tuple[str, ...]) -> None:
    """Refuse (CheckFailed) a level alignment the plan's accelerometers cannot make."""
    why = plan.reduced_refusal("level")
    if why is not None:
        raise CheckFailed(why)
    if plan.accels != ALL:
        check_level_set(inst)
        if any(e != "average" for e in ests):
            raise CheckFailed("accels: the posterior mean's tape is made for three "
                              "accelerometers (Chart I-9): use the simple average")


def level_alignment_procedure(st: IsuDrivers, run: Run, options: AlignmentOptions,
                              mirror: Outcome | None = None, quick: bool = False
                              ) -> list[Outcome]:
    """Tick Chart III-4; one Outcome (and Alignment Results Sheet) per technique that
    ``options`` asks for the level method (the simple average when it names none).

    ``options.tapes["level"]``: the posterior mean's tape; its Chart I-8 parameters are checked
    against this experiment's at step 8, and a mismatch stops the step naming the parameter.
    ``mirror``: the mirror alignment of this run, which T is checked against at step 12
    (else the survey's prediction, if the survey was made in this run). ``quick``: the
    quick alignment of I-3.1 way 3 (simple average over ``plan.quick_K`` intervals; sheet
    ``III-4-quick``), which gives the nominal T1 of Chart I-8.
    """
    noise, calib, survey, plan = options.noise, options.calib, options.survey, options.plan
    calibration_id = options.calibration_id
    ests = ("average",) if quick else (options.techniques("level") or ("average",))
    K, dt = plan.quick_K if quick else plan.level_K, plan.level_dt_s
    tapes = {e: t for e in ests if (t := options.tape_for("level", e)) is not None}
    chart, title, suffix = ((f"{CHART}-quick", f"Quick {TITLE.lower()} (I-3.1, way 3)",
                             "_quick") if quick else (CHART, TITLE, ""))
    t_prior = options.nominal_t1()
    inst = Instruments(plan.accels, plan.gyros, prior_t1(survey) if t_prior is None else t_prior)
    with run.sheet(chart, title) as sheet:
        with sheet.step("1", "Verify turn-on procedures and the Alignment Results Sheet "
                        "inputs are completed") as s:
            s.reading = require_turn_on(run) | {
                "K": K, "dt_s": dt, "estimators": list(ests),
                "calibration_id": calibration_id,
                "options": {"mirror_zenith": plan.mirror_zenith, "surveyed_g": plan.surveyed_g},
                "accelerometers": list(plan.accels),
            }
            check_instruments(plan, inst, ests)
        with sheet.step("1a", "(project addition) Set position 0 with bubble-level "
                        "corrections on phi1 and phi3") as s:
            position0 = s.reading = set_position0(st, noise)
        period, s2 = ieu_period_ticks(run, plan.level_period_s)
        with sheet.step("2", "Verify master oscillator and accelerometers are connected to "
                        "the IEU") as s, pl.rereads() as rr:
            s.reading = pl.with_rereads(check_ieu_lines(st, period, False, s2), rr)
        with sheet.step("3", "Set sampling rate on IEU panel") as s:
            spi = int(round(dt / (period * s2)))
            s.reading = {"period_ticks": period, "period_s": period * s2,
                         "samples_per_interval": spi}
        with sheet.step("4", "Acquire ISU mirror one in azimuth with autocollimator") as s:
            s.reading = acquire_mirrors(st, (1,), survey)
        sheet.done("5", "Load level alignment program",
                   {"program": "procedures.isu.alignment.level", "charts": ["III-5", "III-6",
                                                                        "III-7"]})
        with sheet.step("6", "Load calibration constants from current Calibration Results "
                        "Sheet") as s:
            c = calibration_constants(calib, gyros=False)
            s.reading = {"calibration_id": calibration_id,
                         "constants": {f"{i} {p}": v for (i, p), v in c.values.items()}}
        sheet.done("7", "Enter K and Delta t from the Alignment Results Sheet",
                   {"K": K, "dt_s": dt})
        params = experiment_params(plan, noise, survey, c, K, dt, options.nominal_t1())
        with sheet.step("8", "Enter parameters from parameter evaluation program for chosen "
                        "K and Delta t") as s:
            used = {}
            for e in ests:
                if e == "average":
                    continue  # not required for the average (Chart III-4, comment 8)
                tape = tapes.get(e)
                if tape is None:
                    raise CheckFailed(f"no tape for the {e} technique: run Chart I-7")
                check_tape(tape, params)  # ValueError names the differing parameter
                used[e] = tape.sheet.reel_id
            s.reading = {"tapes": used} if used else {"tapes": None,
                                                       "note": "simple average: not required"}
        with sheet.step("9", "Initiate alignment: IEU data, preprocessing (Chart III-5), "
                        "estimation (Chart III-6)") as s:
            record = collect_checked(st, period, spi, K, plan.recover_lost_samples, s2, noise,
                                     plan.ieu_retakes)
            check_record(record, K, dt)
            mats = {e: estimator_matrices(e, K, dt, tapes.get(e)) for e in ests}
            g_est = {e: ((M @ accel_x(record, c) + b) / es.G0).tolist()
                     for e, (M, b) in mats.items()}
            s.reading = record.summary() | {"g_body_g": g_est}
        text10 = "Enter azimuth angle alpha1 from the autocollimator"
        with sheet.step("10", text10 + f" ({plan.alpha_readings} readings)") as s, \
                pl.rereads() as rr:
            rd = read_autocollimators(st, (1,), plan.alpha_readings, survey, noise)[1]
            alpha1 = rd["azimuth_deg"]
            theta1 = rd["zenith_deg"] if plan.mirror_zenith else None
            s.reading = pl.with_rereads({"alpha1_deg": alpha1, "theta1_deg": rd["zenith_deg"],
                                         "spread_arcsec": rd["spread_arcsec"]}, rr)
        with sheet.step("11", "Enter test table bubble levels and resolver readouts") as s:
            pos, lev = table_record(st)
            s.reading = {"resolvers_deg": list(pos), "bubble_levels_arcsec": list(lev)}
        with sheet.step("12", "After computer output (Chart III-7), enter T on the Alignment "
                        "Results Sheet") as s:
            g_survey = survey_g(survey) if plan.surveyed_g else None
            t_ref = record.t_end + plan.eps_t_s
            reference = ck.attitude_reference(
                survey, survey is not None and run.sheets.get("survey_results") is survey,
                mirror, position0, noise, t_ref)
            out = []
            checked = {}
            for e, (M, b) in mats.items():
                model = level_error_model(record, c, M, b, alpha1, theta1, g_survey, params,
                                          noise, plan.alpha_readings, inst)
                checked[e] = level_checks(e, model, survey, reference)
                sheet_model = AlignmentResults(
                    procedure="level", estimator=e, calibration_id=calibration_id,
                    filtering_parameter_id=tapes[e].sheet.reel_id if e in tapes else None,
                    dt_s=dt, K=K, azimuth_alpha1_deg=alpha1, table_position_deg=pos,
                    bubble_levels_arcsec=lev, t=model["t"].tolist(), t_ref_s=t_ref,
                    predicted_sigma_arcsec=tuple(model["predicted"]),
                    physical_limit_arcsec=tuple(model["limit"]),
                    options={"theta1_deg": theta1, "g_survey_g": g_survey},
                    notes=[f"IEU {record.K * spi} samples of {period} S2^T pulses; "
                           f"{len(record.recoveries)} recovered by RESEND"]
                    + ([f"{inst.describe()}: the absent accelerometer's component from the "
                        "surveyed |g| (III-2.2)"] if plan.accels != ALL else []),
                )
                run.save_sheet(f"alignment_results_level_{e}{suffix}", sheet_model)
                out.append(Outcome("level", e, K, dt, model["t"], t_ref, model["predicted"],
                                   model["limit"], sheet_model,
                                   {"parts": model["parts"], "g_body_g": model["g_b"].tolist(),
                                    "recovered": record.recoveries,
                                    "ieu_samples": record.raw}))
            s.reading = {o.estimator: {"t": o.t.tolist(),
                                       "predicted_sigma_arcsec": o.predicted_sigma_arcsec,
                                       "checks": checked[o.estimator]}
                         for o in out}
    return out
