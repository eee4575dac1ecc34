"""``[calibration]``: the options report 000 leaves to the operator of a calibration day.

Absent (None) in the default config, so a default day's record is unchanged; each field
cites the section that offers the choice.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from station.config.alignment import AsTuple  # TOML arrays as the strict model's tuples

TiltDeg = Annotated[float, Field(gt=0.0, lt=90.0)]


class CalibrationOptions(BaseModel):
    """Bubble-level corrections in positions 7-15 (II-6.1): always advised for the
    accelerometers (Charts II-13, II-14), optional for the gyros (Charts II-11, II-12).
    False runs those positions uncorrected: the table keeps the survey's one level
    reading (Chart I-2 step 5), the uncorrected cases of Charts II-21/II-22."""

    model_config = ConfigDict(defer_build=True, extra="forbid", frozen=True, strict=True)

    bubble_gyro: bool = True
    bubble_accel: bool = True
    # Chart II-6 step 13's remark: if phi3 can be turned accurately with the table in motion,
    # the table need not stop between positions m and m + 1 (1-6)
    turn_phi3_moving: bool = False
    # II-6.1's resolver-setting precisions (one, two or three): phi3, phi4 set to the nearest
    # multiple of this, arcsec (0: as precisely as the table sets, the default); the scale
    # factor positions 1-6 can take about one degree (3600), the accelerometers the finest
    precision_scale_factor_arcsec: float = Field(0.0, ge=0, le=3600.0)
    precision_gyro_arcsec: float = Field(0.0, ge=0, le=3600.0)
    precision_accel_arcsec: float = Field(0.0, ge=0, le=3600.0)
    # the laboratory's result on the Calibration Results Sheet (issue 19): the manual's
    # closed forms (II-4.2, II-4.3) or the all-positions least-squares fit shown beside them
    estimator: Literal["closed-form", "all-positions"] = "closed-form"
    # issue 19, beyond the manual: after Chart II-14 (chart II-14E), per tilt six static
    # positions (four at 45 deg) with each accelerometer's input axis that far from vertical,
    # both signs (II-5's positions 7-15 scheme, Chart II-14's bisector generalized); only the
    # all-positions fit takes them
    extra_accel_tilts_deg: Annotated[tuple[TiltDeg, ...], AsTuple,
                                     Field(max_length=4)] = ()
    # II-5.2's alternative gyro gate for the static positions 7-15 (Charts II-11, II-12):
    # "clock" counts gyro pulses over a preset of clock ticks (the manual's choice);
    # "pulses" counts clock ticks over a preset number of each gyro's pulses (smaller
    # quantization; the number set at each position, procedures.isu.pulse_gate)
    gyro_gate: Literal["clock", "pulses"] = "clock"
    # II-5: with enough counters the gyro and accelerometer readings of positions 7-14 are
    # taken in one setting of the table (counters 1-6 the strings, 7-9 the gyros, 10-12 the
    # gyros again when there are 12); ``counters``: the rack's frequency counters (6 as
    # report 000's laboratory; more only when asked)
    simultaneous: bool = False
    counters: int = Field(6, ge=6, le=12)
    # the error model (issue 18, beyond the manual): how well the gyros' rebalance sampling
    # clock is known against the counter clock, ppm. The edges' sampling offsets of a clock
    # gate differ by frac(T f_s), known when T f_s times the ppm is well under one period
    # (positions 1-6: whole turns of 24 s are whole periods of the default 19.2 kHz); 0,
    # the default: the simulated ISU's rebalance loops and the counters both run on the
    # master oscillator; a large value (1000) makes the edges independent (1/6 a period^2)
    gyro_sample_clock_ppm: float = Field(0.0, ge=0, le=1000.0)

    @model_validator(mode="after")
    def _enough_counters(self) -> CalibrationOptions:
        if self.simultaneous and self.counters < 9:
            raise ValueError(f"simultaneous = true needs counters >= 9 (6 accelerometer strings "
                             f"and 3 gyros), got counters = {self.counters}")
        if self.simultaneous and self.gyro_gate != "clock":
            raise ValueError("simultaneous = true takes gyro_gate = \"clock\" (the gyros' "
                             "gates run inside the accelerometers')")
        if self.simultaneous and (self.bubble_gyro != self.bubble_accel
                                  or self.precision_gyro_arcsec != self.precision_accel_arcsec):
            raise ValueError("simultaneous = true: gyros and accelerometers share each "
                             "setting, so bubble_gyro = bubble_accel and precision_gyro_arcsec "
                             "= precision_accel_arcsec")
        return self

    def precisions(self) -> dict[str, float]:
        """Setting precision (arcsec) by setting kind: "R" positions 1-6, "G" gyro and "A"
        accelerometer positions 7-15; only those given."""
        out = {"R": self.precision_scale_factor_arcsec, "G": self.precision_gyro_arcsec,
               "A": self.precision_accel_arcsec}
        return {k: v for k, v in out.items() if v > 0}

    def uncorrected(self) -> tuple[str, ...]:
        """The position kinds set without corrections: "G" gyro, "A" accelerometer."""
        return tuple(k for k, on in (("G", self.bubble_gyro), ("A", self.bubble_accel))
                     if not on)


def set_to(deg: float, precision_arcsec: float) -> float:
    """A resolver setting (deg) to the nearest multiple of ``precision_arcsec`` (0: as is)."""
    if precision_arcsec <= 0:
        return deg
    q = precision_arcsec / 3600.0
    return round(deg / q) * q
