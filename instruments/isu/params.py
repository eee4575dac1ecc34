"""Instrument parameters (noise, fields of view, latencies), in the lab's units."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class _Model(BaseModel):
    model_config = ConfigDict(defer_build=True, extra="forbid", frozen=True, allow_inf_nan=False)


class SerialParams(_Model):
    latency_s: float = Field(ge=0, le=1.0)


class AutocollimatorParams(_Model):
    noise_arcsec: float = Field(ge=0)
    fov_deg: float = Field(gt=0, le=5)
    integration_s: float = Field(ge=0)
    zenith_range_deg: tuple[float, float]
    initial_aim_deg: tuple[tuple[float, float], tuple[float, float]]


class BubbleLevelParams(_Model):
    noise_arcsec: float = Field(ge=0)
    resolution_arcsec: float = Field(gt=0)
    range_arcsec: float = Field(gt=0)


class IeuParams(_Model):
    frame_gap_s: float = Field(ge=0)
    max_period_s: float = Field(gt=0)


class InstrumentParams(_Model):
    serial: SerialParams
    autocollimator: AutocollimatorParams
    bubble_level: BubbleLevelParams
    ieu: IeuParams
