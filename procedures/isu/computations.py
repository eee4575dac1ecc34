"""II-4 (Chart II-15): the calibration computations as a check-sheet.

Gathers the survey's constants, the counter settings and outputs of every position
measured, computes the constants Chart II-16 allows (procedures.isu.calibration), fills Q_II
from the nonlinearity fits (II-1.2) and J from the designed J experiment (II-1.3, Chart II-10), and
records the Calibration Results Sheet (Chart II-5).
"""

from __future__ import annotations

import math

import numpy as np

from procedures.isu import carry_forward as cf
from procedures.isu import survey_math as sm
from procedures.isu.calibration import (
    AccelPosition,
    CalibrationData,
    Constants,
    GyroPosition,
    NoiseSpec,
    TableGeometry,
)
from procedures.isu.calibration.all_positions import (
    chosen_correlation,
    fill_columns,
    side_by_side,
    side_columns,
)
from procedures.isu.calibration.checks import K_RESULT, check_residuals, check_string_sums
from procedures.isu.calibration.compute import (
    calibrate_with_correlation,
    closed_forms,
    without,
)
from procedures.isu.calibration.forward import GyroModel
from procedures.isu.calibration.geometry import FIRST_COLUMN
from procedures.isu.calibration.inputs import ExtraAccelPosition
from procedures.isu.calibration.neglected import g_terms
from procedures.isu.carry_forward import PriorSheet
from procedures.isu.count_sigma import (
    BISECTOR_ALONG,
    series_sigmas,
    tilt_change_sigma_arcsec,
)
from procedures.isu.day import DayData
from procedures.isu.j_term import JNoise, j_result
from procedures.isu.nonlinearity import (
    NonlinearityFit,
    fit_nonlinearity,
    q_is_from_fit,
    q_terms,
)
from procedures.isu.plan import DayPlan
from procedures.isu.plausibility import Implausible
from procedures.isu.settings import STRINGS
from procedures.isu.sheets import CalibrationResults, ResultRow, SurveyResults, scale_factor_arcsec
from procedures.isu.site import Site
from procedures.runner import Run
from station.errors import CheckFailed

TITLE = "Calibration computations"
ALL_POSITIONS_SIDE = "procedures.isu.calibration.all_positions:all_positions_side"
STRING_KEY = {c: (int(name[1]), int(name[3])) for c, name in STRINGS.items()}
J_COUNTERS = {7: {3: 2, 4: 3}, 11: {2: 1}}  # position -> counter -> gyro


def _survey(data: DayData) -> SurveyResults:
    """The Survey Results Sheet of the day; a failed check when the survey was not run."""
    if data.survey is None:
        raise CheckFailed("no Survey Results Sheet (Chart I-3): the constants of "
                          "steps 3-4 come from the system survey (Chart I-2)")
    return data.survey


def calibration_data(data: DayData, plan: DayPlan, site: Site,
                     last_d1d3: dict[int, float] | None = None,
                     prior: PriorSheet | None = None) -> CalibrationData:
    """Chart II-15 steps 3-7: the survey's constants and every position's counts; with
    ``prior``, that sheet's prerequisites for the pairs not measured and (unless given) the
    last (D1 D3) of the accelerometers without their bisector position."""
    sv = _survey(data)
    geometry = TableGeometry(
        t_bi=tuple(tuple(r) for r in sv.t_bi),
        phi0_deg=sv.position0_deg,
        settings_deg={int(m): v for m, v in sv.settings_deg.items()},
        uncorrected=plan.options.uncorrected(),
        precision_arcsec=plan.options.precisions(),
    )
    const = Constants(
        g=site.g,
        w_sin_lambda=site.omega_sin_lambda,
        w_cos_lambda=site.omega_cos_lambda,
        s1_t=data.s1,
        s_phi=360.0 / plan.rotation_pulses_per_rev,
        t_br_column2={int(m): tuple(v) for m, v in sv.t_br_column2.items()},
        phi1_level_deg=geometry.phi1_level_deg,
    )
    gyro = {m: GyroPosition(**d) for m, d in data.gyro.items()}
    accel = {
        m: AccelPosition(
            gamma={STRING_KEY[int(c)]: v for c, v in d["gamma"].items()},
            n1={STRING_KEY[int(c)]: v for c, v in d["n1"].items()},
            t0=d["t0"], t1=d["t1"], t_level=d["t_level"],
        )
        for m, d in data.accel.items()
    }
    supplied = {} if prior is None else cf.prior_gyro(prior, set(gyro))
    d1d3, d1d3_sigma = ({}, {}) if prior is None else cf.last_d1d3(prior, set(accel))
    if last_d1d3:
        d1d3, d1d3_sigma = last_d1d3, {}
    extra = {m: ExtraAccelPosition(
        gamma={STRING_KEY[int(c)]: v for c, v in d["gamma"].items()},
        n1={STRING_KEY[int(c)]: v for c, v in d["n1"].items()},
        t0=d["t0"], t1=d["t1"], t_level=d["t_level"], up=tuple(d["up"]),
        north=tuple(d["north"]), setting_deg=tuple(d["setting_deg"]))
        for m, d in data.extra_accel.items()}  # II-14E, beyond the manual: the fit's only
    return CalibrationData(constants=const, gyro=gyro, accel=accel, last_d1d3=d1d3,
                           last_d1d3_sigma=d1d3_sigma, prior_gyro=supplied,
                           geometry=geometry, extra_accel=extra)


def _row(rows: list[ResultRow], inst: str, par: str) -> ResultRow:
    return next(r for r in rows if r.instrument == inst and r.parameter == par)


def _j_noise(rows: list[ResultRow], k: int, m: int, noise: NoiseSpec, gate_s: float,
             dphi_arcsec: float, g: float) -> JNoise:
    """Gyro k's J-gate error sources (``JNoise``): count quantization; angle random walk
    and the pier's tilt change seen by the horizontal input axis; random drift; its rate at
    rest in position m (R and the g terms of this day's rows, O up)."""
    arw = noise.gyro_arw_deg_rt_hr * 3600.0 / 60.0 * math.sqrt(gate_s)  # arcsec
    tilt = (tilt_change_sigma_arcsec(noise, gate_s) / dphi_arcsec) ** 2
    est = {r.parameter: r.estimate for r in rows if r.instrument == f"gyro{k}"}
    rest = g_terms(GyroModel.from_estimates(k, est), FIRST_COLUMN[m], g)
    return JNoise(noise.count_quantization_var, (arw / dphi_arcsec) ** 2,
                  noise.gyro_drift_sigma_deg_hr, noise.gyro_drift_tau_s, rest, tilt, noise)


def _check_speeds(chart: str, k: int, pts: list[dict], fit: NonlinearityFit) -> list[float]:
    """Each speed of a nonlinearity series off the quadratic through the others (sigma)."""
    for p, z in zip(pts, fit["residual_z"], strict=True):
        if abs(z) > K_RESULT:
            raise Implausible(
                f"counter1 or counter{k + 1} (gyro {k})",
                f"Chart {chart} at {p['rate_deg_s']:+g} deg/s: the output frequency is "
                f"{z:+.1f} sigma off the quadratic through the other speeds (limit "
                f"{K_RESULT:g}): a wrong count")
    return fit["residual_z"]


def _dphi_arcsec(rows: list[ResultRow], k: int) -> float:
    """Gyro k's measured scale factor in arcsec/pulse (the class's 3 when not measured)."""
    est = _row(rows, f"gyro{k}", "DeltaPhi").estimate
    return scale_factor_arcsec(est) if est else 3.0


def special_experiments(rows: list[ResultRow], data: DayData, plan: DayPlan, site: Site,
                        noise: NoiseSpec) -> dict[str, list[float]]:
    """Q_II from II-1.2 and J from II-1.3, in place (Chart II-16: special experiments); the
    z of each speed and gate pair against the others (a wrong count stops the step)."""
    checks: dict[str, list[float]] = {}
    along_g: dict[int, tuple[float, float]] = {}  # Chart II-7's a2/a1 and sigma per gyro
    for k, pts in data.nonlinearity.items():
        dphi = _dphi_arcsec(rows, k)
        fit = fit_nonlinearity(pts, series_sigmas(noise, pts, dphi))
        checks[f"II-7 gyro{k}"] = _check_speeds("II-7", k, pts, fit)
        along_g[k] = fit["Q_II"], fit["sigma"]
        r = _row(rows, f"gyro{k}", "Q_II")
        r.estimate, r.sigma = fit["Q_II"], fit["sigma"]
        r.note = "II-1.2 nonlinearity fit (positions 1, 3, 5 at several speeds)"
    for k, pts in data.q_is.items():
        rq = _row(rows, f"gyro{k}", "Q_II")
        dphi = _dphi_arcsec(rows, k)
        gb = [_row(rows, f"gyro{k}", f"G.B{j}").estimate for j in (1, 2, 3)]
        if rq.estimate is None or rq.sigma is None or any(x is None for x in gb):
            continue  # needs Q_II (II-7) and (Q^G)^-1 (positions 1-6)
        fit = fit_nonlinearity(pts, series_sigmas(noise, pts, dphi, BISECTOR_ALONG,
                                                  BISECTOR_ALONG))
        checks[f"II-7Q gyro{k}"] = _check_speeds("II-7Q", k, pts, fit)
        r = _row(rows, f"gyro{k}", "Q_IS")
        r.note = "designed speed series along (G + S)/sqrt2 (docs/special-experiments.md)"
        if k in along_g:  # both series today: Q_II and Q_IS from the two together
            (rq.estimate, rq.sigma), (r.estimate, r.sigma) = q_terms(
                along_g[k], (fit["Q_II"], fit["sigma"]), np.array(gb), k)
            rq.note = ("II-1.2 nonlinearity fit (positions 1, 3, 5 at several speeds) with "
                       "II-7Q's for Q_IS (r.S)")
        else:  # Q_II from another sheet (carried forward)
            r.estimate, r.sigma = q_is_from_fit(fit["Q_II"], fit["sigma"], rq.estimate,
                                                rq.sigma, np.array(gb), k)
    if not data.j_term:
        return checks
    sv = _survey(data)
    for m, counters in J_COUNTERS.items():
        recs = data.j_term.get(m)
        if not recs:
            continue
        phi3, phi4 = sv.settings_deg["1" if m == 7 else "5"]
        t_br = sm.t_br(np.array(sv.t_bi), phi3, phi4)
        for c, k in counters.items():
            rdp = _row(rows, f"gyro{k}", "DeltaPhi")
            gb = [_row(rows, f"gyro{k}", f"G.B{j}").estimate for j in (1, 2, 3)]
            if rdp.estimate is None or any(x is None for x in gb):
                continue  # J needs the scale factor and (Q^G)^-1 (positions 1-6)
            g_r = np.array(gb) @ t_br
            gate = recs[0]["gate_s"]
            dphi_as = scale_factor_arcsec(rdp.estimate)
            jn = _j_noise(rows, k, m, noise, gate, dphi_as, sv.g)
            j, sj, zs = j_result(recs, c, dphi_as, g_r, site.omega_sin_lambda,
                                 plan.j_accel_deg_s2, jn)
            checks[f"II-10 gyro{k}"] = zs
            for i, z in enumerate(zs):
                if abs(z) > K_RESULT:
                    raise Implausible(
                        f"counter{c} (gyro {k})", f"Chart II-10 position {m}, gate pair {i + 1}: "
                        f"J {z:+.1f} sigma off the other pairs' (limit {K_RESULT:g}): a wrong "
                        "count, or the table did not ramp as commanded")
            r = _row(rows, f"gyro{k}", "J")
            r.estimate, r.sigma = j, sj
            r.note = (f"Chart II-10 designed experiment, position {m} "
                      "(docs/special-experiments.md)")
    return checks


def compute_calibration(run: Run, data: DayData, plan: DayPlan, noise: NoiseSpec,
                        site: Site, last_d1d3: dict[int, float] | None = None,
                        prior: PriorSheet | None = None) -> CalibrationResults:
    """Chart II-15 over the day's data. ``prior``: an earlier Calibration Results Sheet
    whose constants stand in for what this run does not measure (carry_forward)."""
    with run.sheet("II-15", TITLE) as sheet:
        with sheet.step("1", "Prepare the data for entry") as s:
            cd = calibration_data(data, plan, site, last_d1d3, prior)
            s.reading = {"gyro_positions": sorted(cd.gyro), "accel_positions": sorted(cd.accel)}
        # issue 19: the all-positions estimator beside the closed forms. On a closed-form day
        # it changes no estimate the steps below read, so it is computed beside them from
        # the data as they are now (Run.meanwhile, issue 17)
        estimator = plan.options.estimator
        side = (run.meanwhile(ALL_POSITIONS_SIDE, data=cd, noise=noise, closed=closed_forms(cd),
                              series=data.nonlinearity)
                if estimator == "closed-form" else None)
        sheet.done("2", "Load the calibration program")
        step3 = cd.constants.model_dump(exclude={"t_br_column2"})
        if prior is not None:
            step3["prerequisites"] = {"source": prior.source, "G.B/DeltaPhi": {
                str(k): {str(j): v[0] for j, v in js.items()}
                for k, js in cd.prior_gyro.items()}}
        sheet.done("3", "Enter g and the Earth-rate components (Survey Results Sheet)", step3)
        sheet.done("4", "Enter T12, T22, T32 of T^BRm for m = 1, 3, 5, 13, 14, 15",
                   {str(m): v for m, v in cd.constants.t_br_column2.items()})
        sheet.done("5", "Enter the counter settings", {"positions": len(cd.gyro) + len(cd.accel)})
        sheet.done("6", "Enter the counter outputs")
        step7: dict | None = {str(k): v for k, v in cd.last_d1d3.items()} or None
        if step7 and prior is not None and not last_d1d3:
            step7["source"] = prior.source
        sheet.done("7", "Last (D1 D3) for accelerometers without positions 13, 14", step7)
        with sheet.step("8", "Compute the constants") as s:
            rows, corr = calibrate_with_correlation(cd, noise)
            # the correlation carried to the alignments is the laboratory's estimator's
            if side is not None:  # the side's columns are of the rows as computed here
                computed = [r.model_copy() for r in rows]
            else:
                chosen = side_by_side(rows, cd, noise, estimator, data.nonlinearity)
                corr = chosen_correlation(rows, chosen, estimator)
            carried = ([] if prior is None else
                       cf.carry_rows(rows, prior, cd.prior_gyro, cd.last_d1d3))
            special = special_experiments(rows, data, plan, site, noise)
            # the data the constants did not need must agree with them (calibration.checks)
            checked = check_residuals(cd, rows, noise)
            sums = check_string_sums(cd, rows, noise)
            if side is not None:
                fill_columns(rows, side_columns(computed, side()))
            s.reading = {"determined": sum(r.estimate is not None for r in rows),
                         "rows": len(rows),
                         "residual_z": {k: v["z"] for k, v in
                                        checked.get("residuals", {}).items()},
                         "string_sum_z": sums, "special_z": special}
            if prior is not None:
                s.reading["carried"] = {"source": prior.source, "rows": carried}
        with sheet.step("9", "Record the valid constants (Chart II-16) on the Calibration "
                        "Results Sheet") as s:
            used = sorted({*data.gyro, *data.accel})
            results = CalibrationResults(rows=rows, positions_used=used,
                                         correlation=without(corr, carried))
            s.reading = {"positions_used": used}
    run.save_sheet("calibration_results", results)
    return results
