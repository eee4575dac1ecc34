"""Configuration of the CIGTF station: a TOML file with a ``[cigtf]`` section.

Only the laboratory's scalar settings are exposed (site latitude, misalignment and noise
magnitudes, slew rate, averaging time); a bad field is refused with a message naming it.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from sim.cigtf_world import CigtfParams
from station.config import read_section


class CigtfConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
    latitude_deg: float | None = Field(None, ge=-89.0, le=89.0)
    level_sd_arcsec: float | None = Field(None, ge=0)
    perpendicular_sd_arcsec: float | None = Field(None, ge=0)
    mount_sd_arcsec: float | None = Field(None, ge=0)
    slew_deg_s: float | None = Field(None, gt=0)
    current_noise_ma: float | None = Field(None, ge=0)
    average_s: float | None = Field(None, gt=0)


def load_cigtf_params(path: str | Path | None) -> CigtfParams:
    """The default CigtfParams with the file's [cigtf] settings applied."""
    if path is None:
        return CigtfParams()
    cfg = read_section(path, "cigtf", CigtfConfig, "CIGTF")
    return replace(CigtfParams(), **{k: v for k, v in cfg.model_dump().items() if v is not None})
