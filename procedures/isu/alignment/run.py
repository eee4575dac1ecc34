"""The alignments of Part III in the laboratory's order, after a calibration.

Mirror alignment (Chart III-2); the parameter evaluation (Chart I-7) of the tapes the
posterior-mean techniques need, unless tapes are supplied; level alignment (Chart III-4) and
gyrocompass alignment (Chart III-8), each record processed by every requested technique.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from procedures.isu.alignment.common import (
    Outcome,
    calibration_constants,
    experiment_params,
    prior_t1,
)
from procedures.isu.alignment.gyrocompass import gyrocompass_procedure
from procedures.isu.alignment.level import level_alignment_procedure
from procedures.isu.alignment.mirror import mirror_alignment_procedure
from procedures.isu.alignment.options import DAY_ESTIMATORS, AlignmentOptions, NominalAttitude
from procedures.isu.alignment.parameter_evaluation import parameter_evaluation
from procedures.isu.alignment.preprocess import Constants, MissingConstants
from procedures.runner import Run

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

__all__ = ["DAY_ESTIMATORS", "PRIOR_SOURCES", "AlignmentOptions", "run_alignments"]

# Where the nominal T1 of Chart I-8 came from, by the plan's way of I-3.1.
PRIOR_SOURCES = {
    "resolvers": "Chart I-4: survey T^BI at the nominal position-0 resolver angles "
                 "(I-3.1, way 2)",
    "autocollimators": "Chart III-2: the mirror alignment by the autocollimators (I-3.1, way 1)",
    "quick": "quick {method} alignment, simple average over {K} x {dt:g} s (I-3.1, way 3)",
}


def run_alignments(st: IsuDrivers, run: Run, options: AlignmentOptions) -> list[Outcome]:
    """Run the alignments ``options.estimators`` names (method -> techniques; default: all three
    methods, level and gyrocompass with both techniques on the same record).

    Tapes missing from ``options.tapes`` are taken from ``options.library`` or produced by
    Chart I-7 in this run (into ``options.tape_dir``, and filed in the library), from the
    nominal T1 the plan's way of I-3.1 gives (``nominal_attitude``); without
    ``options.survey``, the run's own Survey Results Sheet is used.
    """
    if options.survey is None:
        options = replace(options, survey=run.sheets.get("survey_results"))
    plan = options.plan
    out: list[Outcome] = []
    mirror = None
    if "mirror" in options.estimators:
        mirror = mirror_alignment_procedure(st, run, options)
        out.append(mirror)
    need = options.needs_tape()
    if need:
        nominal, mirror = nominal_attitude(st, run, options, mirror)
        options = replace(options, nominal=nominal)
        c = calibration_constants(options.calib, gyros=False)
        dims = {"level": (plan.level_K, plan.level_dt_s),
                "gyrocompass": (plan.gyro_K, plan.gyro_dt_s)}
        exps = {m: (experiment_params(plan, options.noise, options.survey, c, *dims[m],
                                      nominal.t1), nominal.source) for m in need}
        made = parameter_evaluation(run, exps, options.tape_dir, options.library)
        options = replace(options, tapes={**options.tapes, **made})
    if "level" in options.estimators:
        out += level_alignment_procedure(st, run, options, mirror)
    if "gyrocompass" in options.estimators:
        out += gyrocompass_procedure(st, run, options, mirror)
    return out


def nominal_attitude(st: IsuDrivers, run: Run, options: AlignmentOptions,
                     mirror: Outcome | None) -> tuple[NominalAttitude, Outcome | None]:
    """The nominal T1 by the plan's way of I-3.1, and the mirror alignment (made here when
    way 1 needs one and the run has none).

    Way 3 is a quick gyrocompass alignment when the calibration holds every gyro constant,
    else a quick level alignment (its azimuth from the autocollimator); both by the simple
    average over ``plan.quick_K`` intervals."""
    way = options.plan.prior_attitude
    if way == "resolvers":
        return NominalAttitude(prior_t1(options.survey), PRIOR_SOURCES[way]), mirror
    if way == "autocollimators":
        if mirror is None:
            mirror = mirror_alignment_procedure(st, run, options)
        return NominalAttitude(mirror.t, PRIOR_SOURCES[way]), mirror
    try:
        Constants.from_sheet(options.calib, True)
        method, procedure, dt = ("gyrocompass", gyrocompass_procedure,
                                 options.plan.gyro_dt_s)
    except MissingConstants:
        method, procedure, dt = "level", level_alignment_procedure, options.plan.level_dt_s
    (quick,) = procedure(st, run, options, mirror, quick=True)
    source = PRIOR_SOURCES["quick"].format(method=method, K=options.plan.quick_K, dt=dt)
    return NominalAttitude(quick.t, source), mirror
