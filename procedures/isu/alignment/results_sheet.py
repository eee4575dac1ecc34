"""Alignment Results Sheet (Chart III-1) and the plan of the alignment procedures.

Lab units at this boundary: degrees, arcsec, seconds, g, deg/hr.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from procedures.sheets import SheetHeader

METHODS = ("mirror", "level", "gyrocompass")
ESTIMATORS = ("average", "posterior", "hybrid")


class _Sheet(BaseModel):
    model_config = ConfigDict(extra="forbid")


class AlignmentResults(_Sheet):
    """Chart III-1, one per alignment (and per estimation technique applied to its data).

    ``t`` is T with T_ij = E_i . B_j (columns: body axes in up, east, north components).
    ``t_ref_s`` is the time T refers to: the mean reading time for mirror alignment, t* (the
    end of the data plus eps_t, Chart I-9) for level and gyrocompass alignment.
    """

    procedure: Literal["mirror", "level", "gyrocompass"]
    estimator: Literal["average", "posterior", "hybrid"]
    calibration_id: str | None = None
    filtering_parameter_id: str | None = None  # reel of the tape (posterior / hybrid)
    dt_s: float | None = None
    K: int | None = None
    azimuth_alpha1_deg: float | None = None  # level input
    autocollimator_deg: tuple[float, float, float, float] | None = None  # a1, th1, a2, th2
    table_position_deg: tuple[float, float, float, float]
    bubble_levels_arcsec: tuple[float, float]
    t: list[list[float]]
    t_ref_s: float
    predicted_sigma_arcsec: tuple[float, float, float]  # about east, north, up
    physical_limit_arcsec: tuple[float, float, float]
    options: dict[str, float | bool | None] = Field(default_factory=dict)
    notes: list[str] = Field(default_factory=list)
    header: SheetHeader | None = None


class AlignPlan(_Sheet):
    """Operator choices for the alignments (the Alignment Results Sheet's inputs).

    Level: 5 minutes of 2 s intervals; gyrocompass: 10 minutes of 5 s intervals (the Earth
    rate's east component, the azimuth's only source, needs the longer record). The IEU
    sample period divides each interval (four and five samples) and stays well under the
    string registers' overflow (2 s).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    mirror_readings: int = Field(8, ge=1, description="autocollimator readings per mirror")
    alpha_readings: int = Field(8, ge=1, description="mirror-1 azimuth readings (level)")
    level_K: int = Field(150, ge=1)
    level_dt_s: float = Field(2.0, gt=0)
    level_period_s: float = Field(0.5, gt=0)
    gyro_K: int = Field(120, ge=1)
    gyro_dt_s: float = Field(5.0, gt=0)
    gyro_period_s: float = Field(1.0, gt=0)
    eps_t_s: float = Field(1.0, ge=0, description="Chart I-9 prediction time after the data")
    sigma_g_g: float = Field(1e-3, gt=0, description="Chart I-8 rms error of g~ (g)")
    sigma_theta_arcsec: float = Field(60.0, gt=0, description="Chart I-8 prior vertical error")
    recover_lost_samples: bool = True
    # records taken again when a sample's counts disagree with its neighbours (sampling)
    ieu_retakes: Annotated[int, Field(ge=0)] = 1
    # options of III-2.2 and III-3.2
    mirror_zenith: bool = False  # level: M1.U = cos(theta1) from the autocollimator
    surveyed_g: bool = False  # level and gyrocompass: |g| from the survey
    surveyed_earth_rate: bool = False  # gyrocompass: |omega^E| from the survey
    known_colatitude: bool = False  # gyrocompass: W.U = cos(colatitude) from the survey

    @model_validator(mode="after")
    def _whole_samples(self) -> AlignPlan:
        for name, dt, per in (("level", self.level_dt_s, self.level_period_s),
                              ("gyro", self.gyro_dt_s, self.gyro_period_s)):
            n = dt / per
            if abs(n - round(n)) > 1e-9 or round(n) < 1:
                raise ValueError(f"{name}: Delta t {dt} s is not a whole number of IEU "
                                 f"samples of {per} s")
        return self
