"""Station configuration (TOML -> pydantic): site, truth, noise, instruments and links.

A user file is merged over the embedded default, so it need only name what it changes.
Unknown or malformed fields are refused with a message naming the field.
"""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

import config as config_pkg
from instruments.params import InstrumentParams
from sim.params import (
    EnvironmentParams,
    IsuParams,
    OscillatorParams,
    SiteParams,
    TableParams,
    WorldParams,
)

SERIAL_INSTRUMENTS = (
    "table",
    "patch_panel",
    *(f"counter{i}" for i in range(1, 7)),
    "autocollimator1",
    "autocollimator2",
    "bubble_levels",
    "oscillator",
)


class ConfigError(ValueError):
    """A configuration that cannot be used; the message names the file and the field."""


def read_section(path: str | Path, section: str, model: type[BaseModel], what: str):
    """One TOML section validated by ``model``; every failure is a ConfigError naming the
    file and the field (``section.field``)."""
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f).get(section, {})
    except FileNotFoundError:
        raise ConfigError(f"configuration file not found: {path}") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path} is not valid TOML: {e}") from None
    try:
        return model.model_validate(data)
    except ValidationError as e:
        lines = [f"invalid {what} configuration in {path}:"]
        lines += [f"  {section}.{'.'.join(map(str, er['loc']))}: {er['msg']}"
                  for er in e.errors()]
        raise ConfigError("\n".join(lines)) from None


class CanLink(BaseModel):
    model_config = ConfigDict(extra="allow", frozen=True)
    interface: str
    channel: str


class Links(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    serial: dict[str, str]
    can: CanLink

    @field_validator("serial")
    @classmethod
    def _every_instrument(cls, v: dict[str, str]) -> dict[str, str]:
        missing = [n for n in SERIAL_INSTRUMENTS if n not in v]
        unknown = [n for n in v if n not in SERIAL_INSTRUMENTS]
        if missing or unknown:
            parts = []
            if missing:
                parts.append(f"missing {', '.join(missing)}")
            if unknown:
                parts.append(f"unknown instrument {', '.join(unknown)}")
            raise ValueError("; ".join(parts))
        return v


class StationConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    seed: int = Field(ge=0)
    site: SiteParams
    environment: EnvironmentParams
    table: TableParams
    isu: IsuParams
    oscillator: OscillatorParams
    instruments: InstrumentParams
    links: Links

    def world_params(self) -> WorldParams:
        return WorldParams(
            site=self.site,
            environment=self.environment,
            table=self.table,
            isu=self.isu,
            oscillator=self.oscillator,
        )


def _merge(base: dict, over: dict) -> dict:
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def default_dict() -> dict:
    with open(config_pkg.path(config_pkg.DEFAULT_CONFIG), "rb") as f:
        return tomllib.load(f)


def _describe(e: ValidationError, source: str) -> str:
    lines = [f"invalid station configuration in {source}:"]
    for err in e.errors():
        loc = ".".join(str(x) for x in err["loc"])
        lines.append(f"  {loc}: {err['msg']}")
    return "\n".join(lines)


def load_config(
    path: str | Path | None = None, seed: int | None = None, overrides: dict | None = None
) -> StationConfig:
    """The embedded default, with a user TOML file and then ``overrides`` merged over it."""
    data = default_dict()
    source = "the embedded default"
    if path is not None:
        source = str(path)
        try:
            with open(path, "rb") as f:
                data = _merge(data, tomllib.load(f))
        except FileNotFoundError:
            raise ConfigError(f"configuration file not found: {path}") from None
        except tomllib.TOMLDecodeError as e:
            raise ConfigError(f"{path} is not valid TOML: {e}") from None
    if overrides:
        data = _merge(data, overrides)
    if seed is not None:
        data["seed"] = seed
    try:
        return StationConfig.model_validate(data)
    except ValidationError as e:
        raise ConfigError(_describe(e, source)) from None
