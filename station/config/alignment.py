"""The alignment plan of Part III (the ``[alignment]`` table of the ISU file): every option
the manual gives the operator of an alignment, and where the tapes are kept.

``AlignPlan`` is what the alignment check-sheets read (K, Delta t and the IEU period of each
method, the Chart I-8 inputs, the options of III-2.2 and III-3.2, and which of the three ways
of I-3.1 gives the nominal attitude T1); ``AlignmentSettings`` adds the tape library, a
station matter rather than an experiment's. Lab units at this boundary: s, g, arcsec.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, field_validator, model_validator

# TOML arrays arrive as lists; the strict models hold tuples. (sim.isu.params has the same
# converter; the procedures read this module and may not reach the simulator.)
AsTuple = BeforeValidator(lambda v: tuple(v) if isinstance(v, list) else v)

# I-3.1 lists three ways to the nominal T1 of Chart I-8: the autocollimators (Chart III-3:
# here the mirror alignment of Chart III-2), the resolvers with T^BI of the survey (Chart
# I-4), and a quick gyrocompass alignment (or a level alignment with the simple average).
PRIOR_ATTITUDES = ("resolvers", "autocollimators", "quick")
PriorAttitude = Literal["resolvers", "autocollimators", "quick"]
Instrument = Literal[1, 2, 3]
# The survey inputs a reduced instrument set needs (III-2.2, III-3.2).
SURVEY_INPUTS = ("surveyed_g", "surveyed_earth_rate", "known_colatitude")


class AlignPlan(BaseModel):
    """Operator choices for the alignments (the Alignment Results Sheet's inputs).

    Level: 5 minutes of 2 s intervals; gyrocompass: 10 minutes of 5 s intervals (the Earth
    rate's east component, the azimuth's only source, needs the longer record). The IEU
    sample period divides each interval (four and five samples) and stays well under the
    string registers' overflow (2 s). The quick alignment of I-3.1 way 3 is a gyrocompass
    alignment by the simple average over ``quick_K`` intervals of the gyrocompass Delta t.
    """

    model_config = ConfigDict(defer_build=True, extra="forbid", frozen=True, allow_inf_nan=False)

    mirror_readings: int = Field(8, ge=1, le=1000,
                                 description="autocollimator readings per mirror")
    alpha_readings: int = Field(8, ge=1, le=1000, description="mirror-1 azimuth readings (level)")
    level_K: int = Field(150, ge=1, le=20000)
    level_dt_s: float = Field(2.0, gt=0, le=3600.0)
    level_period_s: float = Field(0.5, gt=0, le=2.0)
    gyro_K: int = Field(120, ge=1, le=20000)
    gyro_dt_s: float = Field(5.0, gt=0, le=3600.0)
    gyro_period_s: float = Field(1.0, gt=0, le=2.0)
    eps_t_s: float = Field(1.0, ge=0, le=3600.0,
                           description="Chart I-9 prediction time after the data")
    sigma_g_g: float = Field(1e-3, gt=0, le=0.1, description="Chart I-8 rms error of g~ (g)")
    sigma_theta_arcsec: float = Field(60.0, gt=0, le=36000.0,
                                      description="Chart I-8 prior vertical error")
    recover_lost_samples: bool = True
    # records taken again when a sample's counts disagree with its neighbours (sampling)
    ieu_retakes: Annotated[int, Field(ge=0, le=100)] = 1
    # options of III-2.2 and III-3.2
    mirror_zenith: bool = False  # level: M1.U = cos(theta1) from the autocollimator
    surveyed_g: bool = False  # level and gyrocompass: |g| from the survey
    surveyed_earth_rate: bool = False  # gyrocompass: |omega^E| from the survey
    known_colatitude: bool = False  # gyrocompass: W.U = cos(colatitude) from the survey
    # I-3.1: where the nominal T1 of the Alignment Parameter Evaluation Sheet comes from
    prior_attitude: PriorAttitude = "resolvers"
    quick_K: int = Field(24, ge=2, le=20000, description="intervals of the quick alignment")
    # III-2.2, III-3.2: the instruments the level and gyrocompass alignments use
    accels: Annotated[tuple[Instrument, ...], AsTuple] = (1, 2, 3)
    gyros: Annotated[tuple[Instrument, ...], AsTuple] = (1, 2, 3)

    @field_validator("accels", "gyros")
    @classmethod
    def _distinct(cls, v: tuple[int, ...]) -> tuple[int, ...]:
        if not v or len(set(v)) != len(v):
            raise ValueError("name each instrument once, at least one (1, 2, 3)")
        return tuple(sorted(v))

    def reduced_refusal(self, method: str) -> str | None:
        """Why this plan's instrument set cannot serve ``method`` (None: it can); the
        geometry is checked when the alignment runs (procedures.isu.alignment.reduced)."""
        if method == "mirror" or (self.accels == (1, 2, 3) and self.gyros == (1, 2, 3)):
            return None
        if method == "level":
            if len(self.accels) < 2:
                return "accels: the level alignment needs two accelerometers at least"
            if len(self.accels) < 3 and not self.surveyed_g:
                return "accels: two accelerometers need the surveyed |g| (surveyed_g, III-2.2)"
            return None
        missing = [n for n in SURVEY_INPUTS if not getattr(self, n)]
        if missing:
            return (f"accels/gyros: a reduced gyrocompass alignment needs every survey input "
                    f"(III-3.2): set {', '.join(missing)}")
        if len(self.accels) + len(self.gyros) < 3:
            return "accels/gyros: the gyrocompass alignment needs three instruments at least"
        return None

    @model_validator(mode="after")
    def _whole_samples(self) -> AlignPlan:
        for name, dt, per in (("level", self.level_dt_s, self.level_period_s),
                              ("gyro", self.gyro_dt_s, self.gyro_period_s)):
            n = dt / per
            if not math.isfinite(n):  # a period so short the count overflows a float
                raise ValueError(f"{name}: IEU samples of {per} s are too short to count "
                                 f"in Delta t {dt} s")
            if abs(n - round(n)) > 1e-9 or round(n) < 1:
                raise ValueError(f"{name}: Delta t {dt} s is not a whole number of IEU "
                                 f"samples of {per} s")
        return self


class AlignmentSettings(AlignPlan):
    """``[alignment]``: the plan, and the tape library (a directory of Chart I-7 tapes
    indexed by their Chart I-8 parameters; None: each run makes its own tapes)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, strict=True)

    tape_library: str | None = Field(None, min_length=1)

    def plan(self) -> AlignPlan:
        return AlignPlan.model_validate(self.model_dump(exclude={"tape_library"}))
