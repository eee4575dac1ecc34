"""Mirror alignment (Chart III-2, steps 1-7; computation Chart III-3; sheet Chart III-1).

Both autocollimators read their mirror alternately, ``n`` readings each; the means go into
Chart III-3. T refers to the mean time of the readings: the readings are short (about a
second a pair), so the pier's motion during them (a 1 arcsec wobble at 1 cycle/min) is
nearly linear and cancels about that time; what remains is in the error model.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from procedures.isu import plausibility as pl
from procedures.isu.alignment import checks as ck
from procedures.isu.alignment import error_model as em
from procedures.isu.alignment.align_math import ARCSEC, mirror_alignment
from procedures.isu.alignment.common import (
    Outcome,
    ac_sigma_arcsec,
    acquire_mirrors,
    read_autocollimators,
    require_turn_on,
    set_position0,
    table_record,
)
from procedures.isu.alignment.options import AlignmentOptions
from procedures.isu.alignment.results_sheet import AlignmentResults
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.sheets import SurveyResults
from procedures.runner import Run

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

CHART = "III-2"
TITLE = "Mirror alignment"


def mirror_error_model(ac_deg: tuple[float, float, float, float], times: Sequence[float],
                       t_ref: float, n: int, noise: NoiseSpec) -> dict:
    """Predicted covariance of phi (U, E, N) and the physical limit, for Chart III-3."""
    x0 = np.asarray(ac_deg, dtype=float)
    t0 = mirror_alignment(*x0)
    s = ac_sigma_arcsec(noise, n) / 3600.0  # deg, across the line of sight
    # an azimuth reading's noise is s / sin(zenith) in azimuth angle
    sig = np.array([s / np.sin(np.radians(x0[1])), s, s / np.sin(np.radians(x0[3])), s])
    jac = em.jacobian(em.phi_of(t0, lambda x: mirror_alignment(*x)), x0, 1e-5)
    cov = jac @ np.diag(sig**2) @ jac.T
    motion = em.tilt_motion_cov(noise, times, t_ref)
    cov_total = cov.copy()
    cov_total[1:, 1:] += motion
    limit = ac_sigma_arcsec(noise, n)
    return {"cov": cov_total, "predicted": em.as_enu_arcsec(cov_total),
            "limit": [limit, limit, limit],
            "motion_arcsec": [float(np.sqrt(motion[i, i]) / ARCSEC) for i in (0, 1)]}


def check_against_survey(t: np.ndarray, predicted: Sequence[float], survey: SurveyResults,
                         position0: dict,
                         noise: NoiseSpec, t_ref: float) -> dict:
    """The mirror alignment's T against the survey's prediction at the same setting, with
    the pier's tilt change between the levelling and the readings."""
    t_pred = ck.survey_t(survey, position0["resolvers_deg"], position0["level_arcsec"])
    return ck.check_attitude(
        "mirror alignment", t, predicted, t_pred, ck.survey_sigma_arcsec(noise),
        "the survey's T^BI (Chart I-3) at this setting",
        "the autocollimators' readings (autocollimator1, autocollimator2), the table's "
        "setting (table) or its levelling (bubble_levels) disagree with the survey",
        ck.tilt_motion_arcsec(noise, t_ref - float(position0["t_s"])))


def mirror_alignment_procedure(st: IsuDrivers, run: Run, options: AlignmentOptions) -> Outcome:
    """Tick Chart III-2 and return the mirror alignment (Chart III-1 saved in the run).

    The readings must agree among themselves (``read_autocollimators``) and, when the survey
    was made in this run, T must agree with the survey's prediction (``checks``). Uses the
    noise specification, the survey and the plan's number of readings of ``options``."""
    noise, survey = options.noise, options.survey
    n = options.plan.mirror_readings
    with run.sheet(CHART, TITLE) as sheet:
        with sheet.step("1", "Verify turn-on procedures are completed (Part I, Section 1)") as s:
            s.reading = require_turn_on(run)
        with sheet.step("1a", "(project addition) Set position 0 with bubble-level "
                        "corrections on phi1 and phi3") as s:
            position0 = s.reading = set_position0(st, noise)
        with sheet.step("2", "Align autocollimators to mirrors") as s:
            s.reading = acquire_mirrors(st, (1, 2), survey)
        sheet.done("3", "Load the mirror alignment program",
                   {"program": "procedures.isu.alignment.mirror", "chart": "III-3"})
        with sheet.step("4", f"Enter azimuths and zeniths from the autocollimators "
                        f"({n} readings each, averaged) on the Alignment Results Sheet") as s, \
                pl.rereads() as rr:
            rd = read_autocollimators(st, (1, 2), n, survey, noise)
            ac = (rd[1]["azimuth_deg"], rd[1]["zenith_deg"], rd[2]["azimuth_deg"],
                  rd[2]["zenith_deg"])
            times = rd[1]["times_s"] + rd[2]["times_s"]
            t_ref = float(np.mean(times))
            s.reading = pl.with_rereads(
                {"autocollimator_deg": list(ac), "n_readings": n, "t_ref_s": t_ref,
                 "spread_arcsec": {str(k): rd[k]["spread_arcsec"] for k in (1, 2)},
                 "span_s": [min(times), max(times)]}, rr)
        sheet.done("5", "Enter alpha1, alpha2, theta1, theta2 into the computer",
                   {"autocollimator_deg": list(ac)})
        with sheet.step("6", "Compute and output the alignment matrix T (Chart III-3)") as s:
            t = mirror_alignment(*ac)
            model = mirror_error_model(ac, times, t_ref, n, noise)
            checked = None
            surveyed_here = run.sheets.get("survey_results") is survey
            if survey is not None and surveyed_here:
                checked = check_against_survey(t, model["predicted"], survey, position0, noise,
                                               t_ref)
            s.reading = {"t": t.tolist(), "predicted_sigma_arcsec": model["predicted"],
                         **({"checks": {"survey": checked}} if checked else {})}
        with sheet.step("7", "Record T, table resolver settings and bubble levels on the "
                        "Alignment Results Sheet (Chart III-1)") as s:
            pos, lev = table_record(st)
            results = AlignmentResults(
                procedure="mirror", estimator="average", K=n,
                autocollimator_deg=ac, table_position_deg=pos, bubble_levels_arcsec=lev,
                t=t.tolist(), t_ref_s=t_ref,
                predicted_sigma_arcsec=tuple(model["predicted"]),
                physical_limit_arcsec=tuple(model["limit"]),
                notes=[f"{n} readings per mirror, alternating; T at their mean time"],
            )
            run.save_sheet("alignment_results_mirror", results)
            s.reading = {"sheet": "alignment_results_mirror"}
    dt = (max(times) - min(times)) / max(n - 1, 1) if n > 1 else 0.0
    return Outcome("mirror", "average", n, float(dt), t, t_ref, model["predicted"],
                   model["limit"], results, {"motion_arcsec": model["motion_arcsec"]})
