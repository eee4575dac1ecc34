"""What a calibration day is asked to achieve, and the knobs the check-sheets leave open.

Required accuracies (the config's ``[plan]``, station.config.plan) are turned into
data-collection times by procedures.isu.settings (II-6.2, procedures.isu.accuracy); the rest
are laboratory choices the report leaves to the operator.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator

from station.config.calibration import CalibrationOptions
from station.config.plan import PlanSettings


class DayPlan(BaseModel):
    model_config = ConfigDict(defer_build=True, extra="forbid", frozen=True)

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
    # A study's fixed collection times (station plan --verify sweeps them): a gate given here
    # takes this time whatever the requirements; None: the time the requirement implies
    study_gyro_gate_s: float | None = Field(None, gt=0)  # gyro positions 7-15
    study_accel_vertical_s: float | None = Field(None, gt=0)
    study_accel_horizontal_s: float | None = Field(None, gt=0)

    @model_validator(mode="after")
    def _admissible(self) -> DayPlan:
        longest = 60.0 * self.requirements.max_gate_minutes
        for name in STUDY_GATES:
            v = getattr(self, name)
            if v is not None and v > longest:
                raise ValueError(f"{name} = {v:g} s: longer than max_gate_minutes "
                                 f"{self.requirements.max_gate_minutes:g}")
        return self

    def study_times(self) -> dict[str, float]:
        """The gates fixed for a study (procedures.isu.accuracy gate name -> seconds)."""
        return {gate: float(v) for name, gate in STUDY_GATES.items()
                if (v := getattr(self, name)) is not None}


# DayPlan field -> the gate it fixes (procedures.isu.accuracy.GATES)
STUDY_GATES = {"study_gyro_gate_s": "gyro 7-15", "study_accel_vertical_s": "accel vertical",
               "study_accel_horizontal_s": "accel horizontal"}
