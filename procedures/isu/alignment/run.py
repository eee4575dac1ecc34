"""The alignments of Part III in the laboratory's order, after a calibration.

Mirror alignment (Chart III-2); the parameter evaluation (Chart I-7) of the tapes the
posterior-mean techniques need, unless tapes are supplied; level alignment (Chart III-4) and
gyrocompass alignment (Chart III-8), each record processed by every requested technique.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from procedures.isu.alignment.common import (
    Outcome,
    calibration_constants,
    canonical_estimator,
    experiment_params,
)
from procedures.isu.alignment.gyrocompass import gyrocompass_procedure
from procedures.isu.alignment.level import level_alignment_procedure
from procedures.isu.alignment.mirror import mirror_alignment_procedure
from procedures.isu.alignment.parameter_evaluation import parameter_evaluation
from procedures.isu.alignment.parameter_sheet import Tape
from procedures.isu.alignment.results_sheet import AlignPlan
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.sheets import CalibrationResults, SurveyResults
from procedures.runner import Run

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

DAY_ESTIMATORS = {"mirror": ("average",), "level": ("average", "posterior"),
                  "gyrocompass": ("average", "hybrid")}
PRIOR_SOURCE = "Chart I-4: survey T^BI at the nominal position-0 resolver angles (I-3.1, way 2)"


def run_alignments(
    st: IsuDrivers,
    run: Run,
    noise: NoiseSpec,
    calib: CalibrationResults,
    survey: SurveyResults | None = None,
    site: dict | None = None,
    plan: AlignPlan | None = None,
    estimators: dict[str, tuple[str, ...]] | None = None,
    tapes: dict[str, Tape] | None = None,
    tape_dir: Path | None = None,
    calibration_id: str | None = None,
) -> list[Outcome]:
    """Run the alignments named in ``estimators`` (method -> techniques; default: all three
    methods, level and gyrocompass with both techniques on the same record).

    ``tapes``: "level" / "gyrocompass" -> a tape to use (checked at Chart III-4 step 8 /
    III-8 step 7); missing tapes are produced by Chart I-7 in this run.
    """
    plan = plan or AlignPlan()
    est = {m: tuple(dict.fromkeys(canonical_estimator(m, e) for e in v))
           for m, v in (estimators or DAY_ESTIMATORS).items()}
    tapes = dict(tapes or {})
    if survey is None:
        survey = run.sheets.get("survey_results")
    out: list[Outcome] = []
    mirror = None
    if "mirror" in est:
        mirror = mirror_alignment_procedure(st, run, noise, survey, plan)
        out.append(mirror)
    need = {m for m in ("level", "gyrocompass")
            if m in est and any(e != "average" for e in est[m]) and m not in tapes}
    if need:
        c = calibration_constants(calib, gyros=False)
        dims = {"level": (plan.level_K, plan.level_dt_s),
                "gyrocompass": (plan.gyro_K, plan.gyro_dt_s)}
        exps = {m: (experiment_params(plan, noise, survey, c, *dims[m]), PRIOR_SOURCE)
                for m in ("level", "gyrocompass") if m in need}
        tapes.update(parameter_evaluation(run, exps, tape_dir))
    if "level" in est:
        lt = {e: tapes["level"] for e in est["level"] if e != "average"}
        out += level_alignment_procedure(st, run, noise, calib, survey, plan, est["level"],
                                         lt, calibration_id, mirror)
    if "gyrocompass" in est:
        gt = {e: tapes["gyrocompass"] for e in est["gyrocompass"] if e != "average"}
        out += gyrocompass_procedure(st, run, noise, calib, survey, site, plan,
                                     est["gyrocompass"], gt, calibration_id, mirror)
    return out
