"""Acceptance limits of the three laboratories (the ``[limits]`` tables), validated like the
other sections: a bad field is a one-line ConfigError naming it.

ISU (``[limits]`` of the ISU file): per constant of the Calibration Results Sheet (Chart
II-5), keyed ``gyro1.R``, ``accel2.D0`` (one instrument) or ``gyro.R``, ``accel.D0`` (every
instrument of the kind; a keyed instrument's entry overrides those fields), a band on the
estimate (``max_abs`` about ``nominal``, or an ``interval``) and a required accuracy
(``max_sigma``, the 1-sigma the calibration must reach); per alignment method the largest
predicted 1-sigma error per axis (east, north, azimuth). CIGTF (``[cigtf.limits]``): the
operating and shutdown instabilities (delta, Delta). ESG (``[esg.limits]``): the readout rms
goal. The defaults and their sources: config/default.toml and below; docs/limits.md.
"""

from __future__ import annotations

import math
import re
from typing import Annotated

from pydantic import BaseModel, Field, field_validator, model_validator

from station.config.strict import STRICT

# The rows of the Calibration Results Sheet (Chart II-5), by kind of instrument.
GYRO_PARAMETERS = ("DeltaPhi", "G.B1", "G.B2", "G.B3", "R", "B_I", "B_O", "B_S", "C_II",
                   "C_SS", "C_IS", "C_OS", "C_IO", "Q_II", "Q_IS", "J")
ACCEL_PARAMETERS = ("D1", "A.B1", "A.B2", "A.B3", "D0", "D2", "D3")
INSTRUMENTS = 3  # three gyros and three accelerometers (report 000)
METHODS = ("mirror", "level", "gyrocompass")
# Bounds: far beyond any constant of the sheet (D1 is about 2000) and any attitude sigma.
Value = Annotated[float, Field(ge=-1e6, le=1e6)]
Width = Annotated[float, Field(gt=0, le=1e6)]
Arcsec = Annotated[float, Field(gt=0, le=36000.0)]  # 10 deg
_KEY = re.compile(r"(gyro|accel)([1-9]?)\.(.+)")


class ConstantLimit(BaseModel):
    """A band on one constant's estimate and, optionally, its required accuracy."""

    model_config = STRICT
    nominal: Value | None = None  # centre of max_abs (0 when not given)
    max_abs: Width | None = None  # |estimate - nominal| <= max_abs
    interval: list[Value] | None = None  # [low, high]: low <= estimate <= high
    max_sigma: Width | None = None  # the calibration's 1 sigma <= max_sigma

    @field_validator("interval")
    @classmethod
    def _an_interval(cls, v: list[float] | None) -> list[float] | None:
        if v is not None and (len(v) != 2 or not v[0] < v[1]):
            raise ValueError("an interval is [low, high] with low below high")
        return v

    @model_validator(mode="after")
    def _one_band(self) -> ConstantLimit:
        if self.max_abs is not None and self.interval is not None:
            raise ValueError("give max_abs (about nominal) or interval, not both")
        if self.nominal is not None and self.interval is not None:
            raise ValueError("nominal is the centre of max_abs; an interval has none")
        return self


class AlignmentLimit(BaseModel):
    """The largest predicted 1-sigma attitude error of an alignment, per axis, arcsec."""

    model_config = STRICT
    max_sigma_arcsec: list[Arcsec]

    @field_validator("max_sigma_arcsec")
    @classmethod
    def _three_axes(cls, v: list[float]) -> list[float]:
        if len(v) != 3 or not all(x > 0 and math.isfinite(x) for x in v):
            raise ValueError("three positive numbers: about east, about north, azimuth")
        return v


class IsuLimits(BaseModel):
    """``[limits]`` of the ISU laboratory's file."""

    model_config = STRICT
    constants: dict[str, ConstantLimit] = {}
    alignment: dict[str, AlignmentLimit] = {}

    @field_validator("constants")
    @classmethod
    def _known_rows(cls, v: dict[str, ConstantLimit]) -> dict[str, ConstantLimit]:
        for key in v:
            m = _KEY.fullmatch(key)
            known = GYRO_PARAMETERS if m and m[1] == "gyro" else ACCEL_PARAMETERS
            if m is None or m[3] not in known or (m[2] and int(m[2]) > INSTRUMENTS):
                raise ValueError(f"{key!r} is no row of the Calibration Results Sheet "
                                 "(gyro1..3 or gyro: DeltaPhi, G.B1, R, B_I, ..., J; accel1..3 "
                                 "or accel: D1, A.B1, D0, D2, D3)")
        return v

    @field_validator("alignment")
    @classmethod
    def _known_methods(cls, v: dict[str, AlignmentLimit]) -> dict[str, AlignmentLimit]:
        for key in v:
            if key not in METHODS:
                raise ValueError(f"{key!r} is no alignment method (mirror, level, gyrocompass)")
        return v

    def constant(self, instrument: str, parameter: str) -> ConstantLimit | None:
        """The limit of one row: the kind's entry with the instrument's fields over it."""
        kind = instrument.rstrip("0123456789")
        general = self.constants.get(f"{kind}.{parameter}")
        own = self.constants.get(f"{instrument}.{parameter}")
        if own is None or general is None:
            return own or general
        merged = general.model_dump(exclude_none=True) | own.model_dump(exclude_none=True)
        if "interval" in own.model_fields_set:  # a band of its own replaces the kind's
            merged.pop("max_abs", None)
            merged.pop("nominal", None)
        elif "max_abs" in own.model_fields_set:
            merged.pop("interval", None)
        return ConstantLimit.model_validate(merged)


class CigtfLimits(BaseModel):
    """``[cigtf.limits]``: the gyrocompassing test's instabilities, arcsec (report 001,
    5.3.4 and 5.3.5). The report sets no acceptance value; we chose 20 arcsec for both: a
    gyro that gives north to 1 arcmin at 3 sigma (docs/limits.md); the default fixture
    shows about 5."""

    model_config = STRICT
    max_operating_instability_arcsec: float | None = Field(20.0, gt=0, le=3600.0)  # delta
    max_shutdown_instability_arcsec: float | None = Field(20.0, gt=0, le=3600.0)  # Delta


class EsgLimits(BaseModel):
    """``[esg.limits]``: the readout rms goal, arcsec. Report 004: "demonstration of gyro
    readout to an accuracy of 15 arc-seconds or better" (the program goal)."""

    model_config = STRICT
    readout_rms_arcsec: float | None = Field(15.0, gt=0, le=3600.0)
