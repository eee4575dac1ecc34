"""What a calibration day is asked to achieve, and the knobs the check-sheets leave open.

Required accuracies (the config's ``[plan]``, station.config.plan) are turned into
data-collection times by procedures.isu.settings (II-6.2, procedures.isu.accuracy); the rest
are laboratory choices the report leaves to the operator.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from station.config.calibration import CalibrationOptions
from station.config.plan import PlanSettings


class DayPlan(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    # Required accuracies (1 sigma) and the longest gate, II-6.2 and Charts II-18..II-24
    requirements: PlanSettings = PlanSettings()
    # Operator choices
    table_rate_deg_s: float = Field(15.0, gt=0)  # about 24 s a turn, under gyro saturation
    min_turns: int = Field(10, ge=1)  # II-6.2 advises several whole turns: the default
    rotation_pulses_per_rev: int = Field(1, ge=1)
    nonlinearity_rates_deg_s: tuple[float, ...] = (-15.0, -10.0, -5.0, 5.0, 10.0, 15.0)
    nonlinearity_turns: int = Field(4, ge=1)
    j_accel_deg_s2: float = Field(5.0, gt=0)
    j_rate_deg_s: float = Field(10.0, gt=0)
    warmup_s: float = Field(1800.0, ge=0)
    # II-6.1 options (the config's [calibration]): bubble-level corrections in 7-15
    options: CalibrationOptions = CalibrationOptions()
