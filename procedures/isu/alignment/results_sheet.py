"""Alignment Results Sheet (Chart III-1) and the plan of the alignment procedures.

Lab units at this boundary: degrees, arcsec, seconds, g, deg/hr.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from procedures.sheets import SheetHeader
from station.config.alignment import AlignPlan

__all__ = ["ESTIMATORS", "METHODS", "AlignPlan", "AlignmentResults"]

METHODS = ("mirror", "level", "gyrocompass")
ESTIMATORS = ("average", "posterior", "hybrid")


class _Sheet(BaseModel):
    model_config = ConfigDict(defer_build=True, extra="forbid")


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
