"""The alignments of Part III in the laboratory's order, after a calibration.

Mirror alignment (Chart III-2); the parameter evaluation (Chart I-7) of the tapes the
posterior-mean techniques need, unless tapes are supplied; level alignment (Chart III-4) and
gyrocompass alignment (Chart III-8), each record processed by every requested technique.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from procedures.isu.alignment.common import Outcome, calibration_constants, experiment_params
from procedures.isu.alignment.gyrocompass import gyrocompass_procedure
from procedures.isu.alignment.level import level_alignment_procedure
from procedures.isu.alignment.mirror import mirror_alignment_procedure
from procedures.isu.alignment.options import DAY_ESTIMATORS, AlignmentOptions
from procedures.isu.alignment.parameter_evaluation import parameter_evaluation
from procedures.runner import Run

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

__all__ = ["DAY_ESTIMATORS", "PRIOR_SOURCE", "AlignmentOptions", "run_alignments"]

PRIOR_SOURCE = "Chart I-4: survey T^BI at the nominal position-0 resolver angles (I-3.1, way 2)"


def run_alignments(st: IsuDrivers, run: Run, options: AlignmentOptions) -> list[Outcome]:
    """Run the alignments ``options.estimators`` names (method -> techniques; default: all three
    methods, level and gyrocompass with both techniques on the same record).

    Tapes missing from ``options.tapes`` are produced by Chart I-7 in this run (into
    ``options.tape_dir``); without ``options.survey``, the run's own Survey Results Sheet is used.
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
        c = calibration_constants(options.calib, gyros=False)
        dims = {"level": (plan.level_K, plan.level_dt_s),
                "gyrocompass": (plan.gyro_K, plan.gyro_dt_s)}
        exps = {m: (experiment_params(plan, options.noise, options.survey, c, *dims[m]),
                    PRIOR_SOURCE) for m in need}
        made = parameter_evaluation(run, exps, options.tape_dir)
        options = replace(options, tapes={**options.tapes, **made})
    if "level" in options.estimators:
        out += level_alignment_procedure(st, run, options, mirror)
    if "gyrocompass" in options.estimators:
        out += gyrocompass_procedure(st, run, options, mirror)
    return out
