"""The required accuracies of a calibration day (the ``[plan]`` table of the ISU file, II-6.2).

Report 000 sets every counter preset from a required accuracy (1 sigma): the accuracy gives a
collection time through Charts II-18..II-24, the time gives counts. The defaults are the
figures II-6.2 quotes, which the manual's standard times (10 turns; 10 min gyro; 10 min
vertical, 30 min horizontal accelerometer) meet at the default laboratory, so a default day
keeps those times; procedures.isu.accuracy turns the requirements into times.
"""

from __future__ import annotations

from pydantic import BaseModel, Field, ValidationError

from station.config.assignment import named_item
from station.config.strict import STRICT

# name -> (units, what it bounds, chart): the one list the command line and the sheets use
REQUIREMENT_TEXT = {
    "gyro_scale_factor": ("relative", "sigma(DeltaPhi)/DeltaPhi of each gyro", "II-18"),
    "gyro_drift_deg_hr": ("deg/hr", "sigma of R, B_I g, B_O g, B_S g, C_II g^2, C_SS g^2 of "
                          "each gyro", "II-19"),
    "accel_scale_factor_ppm": ("ppm", "sigma of the vertical combination D1 (A.B_k) + g^2 D1 "
                               "D3 of each accelerometer, relative", "II-21"),
    "accel_bias_micro_g": ("micro-g", "sigma(D0) of each accelerometer, with level "
                           "corrections", "II-24"),
}


class PlanSettings(BaseModel):
    """``[plan]``: required accuracies (1 sigma) and the longest gate the day may use."""

    model_config = STRICT

    gyro_scale_factor: float = Field(1e-4, gt=0, le=0.01,
                                     description="relative, Chart II-18 (1e-4 in one turn)")
    gyro_drift_deg_hr: float = Field(0.02, gt=0, le=10.0,
                                     description="R, Bg, Cg^2, Chart II-19 (0.02 in 10 min)")
    accel_scale_factor_ppm: float = Field(2.0, gt=0, le=1e4,
                                          description="vertical, Chart II-21 (2 in 10 min)")
    accel_bias_micro_g: float = Field(6.0, gt=0, le=1e4, description="D0 with level "
                                      "corrections, Chart II-24 (6 in 30 min)")
    max_gate_minutes: float = Field(60.0, ge=1.0, le=1440.0,
                                    description="no gate (nor the turns of a position) longer")

    def requirements(self) -> dict[str, float]:
        """The required accuracies by name (everything but the maximum gate)."""
        return {n: getattr(self, n) for n in REQUIREMENT_TEXT}


def with_required(plan: PlanSettings, given: list[str]) -> PlanSettings:
    """``plan`` with ``NAME=VALUE`` items (the command line's ``--require``) over it;
    ValueError in one line naming an unknown name or a bad value."""
    names = [*REQUIREMENT_TEXT, "max_gate_minutes"]
    update: dict[str, float] = {}
    for item in given:
        name, text = named_item("--require", item, names,
                                f"give NAME=VALUE with NAME one of {', '.join(names)}")
        try:
            update[name] = float(text)
        except ValueError:
            raise ValueError(f"--require {name}: {text!r} is not a number") from None
    try:
        return PlanSettings.model_validate({**plan.model_dump(), **update})
    except ValidationError as e:
        err = e.errors()[0]
        raise ValueError(f"--require {err['loc'][0]}: {err['msg']}") from None
