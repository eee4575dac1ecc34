"""II-6.1's bubble-level option: positions 7-15 with or without corrections.

Bubble corrections are advised always for the accelerometers and are optional for the gyros
(II-6.1). A position set without them keeps the survey's one level reading (Chart I-2
step 5: the Survey Results Sheet's phi1^0, phi3^0 are the level table's, so the resolver
settings of Chart I-5 are a level table's too): phi1 and phi3 carry the survey's
corrections, and the pier's tilt counts from the survey's reading instead of from a reading
2.5 s before the gate (the uncorrected cases of Charts II-21/II-22).
"""

from __future__ import annotations

from procedures.isu.plan import DayPlan
from procedures.isu.sheets import SurveyResults
from procedures.isu.static_positions import Uncorrected
from procedures.isu.system_survey import POSITION0_DEG


def uncorrected_setting(survey: SurveyResults, t_level: float) -> Uncorrected:
    """The survey's level corrections (deg) on phi1 and phi3: the commanded position 0
    minus what a level table reads there (Chart I-2 step 7)."""
    return Uncorrected(phi1_deg=POSITION0_DEG[0] - survey.position0_deg[0],
                       phi3_deg=POSITION0_DEG[2] - survey.position0_deg[2], t_level=t_level)


def uncorrected_for(plan: DayPlan, survey: SurveyResults, t_level: float | None
                    ) -> dict[str, Uncorrected | None]:
    """Per kind ("G" gyro, "A" accelerometer): None if levelled at each position, else the
    uncorrected setting; ValueError when the survey was carried from an earlier run (its
    reading's instant, and so the tilt since, is not known)."""
    kinds = plan.options.uncorrected()
    if kinds and t_level is None:
        raise ValueError("[calibration] bubble_gyro/bubble_accel false: needs this day's "
                         "survey (Chart I-2), not one carried by --survey")
    out: dict[str, Uncorrected | None] = {"G": None, "A": None}
    for k in kinds:
        out[k] = uncorrected_setting(survey, t_level)  # type: ignore[arg-type]
    return out
