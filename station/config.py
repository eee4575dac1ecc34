"""Station configuration (TOML -> pydantic): site, truth, noise, instruments and links.

A user file is merged over the embedded default, so it need only name what it changes.
Unknown or malformed fields are refused with a message naming the field.
"""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path
from typing import Annotated

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

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
    """python-can settings of the IEU's bus; extra keys go to ``can.Bus`` as given."""

    model_config = ConfigDict(extra="allow", frozen=True)
    interface: str
    channel: str

    @field_validator("interface")
    @classmethod
    def _known_interface(cls, v: str) -> str:
        import can

        import station.links  # noqa: F401  (the ``sim`` interface is a python-can plugin)

        if v not in can.VALID_INTERFACES:
            raise ValueError(f"python-can knows no interface {v!r} (socketcan, socketcand, "
                             "slcan, sim, ...)")
        return v


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

    @model_validator(mode="after")
    def _one_kind_of_rack(self) -> Links:
        """All links simulated (sim://, sim) or none: a hardware profile that leaves an
        instrument out would otherwise inherit the default's sim:// link for it."""
        sim = [n for n, u in self.serial.items() if u.startswith("sim://")]
        if self.can.interface == "sim":
            sim.append("can")
        if sim and len(sim) < len(self.serial) + 1:
            raise ValueError(f"simulated links ({', '.join(sim)}) mixed with hardware links: "
                             "give every instrument its device")
        return self


FAULT_INSTRUMENTS = (*SERIAL_INSTRUMENTS, "ieu")
TABLE_ONLY_FAULTS = ("stall_axis", "stall_after_s")


class FaultSpec(BaseModel):
    """Faults of one instrument for a rehearsal (``[faults.<instrument>]``); defaults: none.

    Applied inside the simulated instruments (instruments/faults.py), so a virtual run and a
    served rack misbehave alike; every random choice is seeded from the run's seed.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)
    latency_s: float = Field(0.0, ge=0, allow_inf_nan=False)  # extra delay per reply / frame
    drop_rate: float = Field(0.0, ge=0, lt=1)  # serial: per reply byte; IEU: per frame
    corrupt_rate: float = Field(0.0, ge=0, lt=1)  # serial: one bit per byte; IEU: one byte
    silent_after_s: float | None = Field(None, ge=0, allow_inf_nan=False)  # sends nothing after
    stall_axis: int | None = Field(None, ge=1, le=4)  # table only: the axis whose drive seizes
    stall_after_s: float = Field(0.0, ge=0, allow_inf_nan=False)  # table only: when it seizes


def _fault_instrument(name: str) -> str:
    if name not in FAULT_INSTRUMENTS:
        raise ValueError(
            f"unknown instrument {name!r} in faults.{name}; known: {', '.join(FAULT_INSTRUMENTS)}"
        )
    return name


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
    faults: dict[Annotated[str, AfterValidator(_fault_instrument)], FaultSpec] = {}

    @field_validator("faults")
    @classmethod
    def _stall_is_the_tables(cls, v: dict[str, FaultSpec]) -> dict[str, FaultSpec]:
        """stall_axis and stall_after_s: table only, and a stall time needs an axis."""
        bad = [
            f"faults.{name}.{field}"
            for name, spec in v.items()
            if name != "table"
            for field in TABLE_ONLY_FAULTS
            if field in spec.model_fields_set
        ]
        if bad:
            raise ValueError(f"{', '.join(bad)}: only the table has axes to stall")
        table = v.get("table")
        if table and "stall_after_s" in table.model_fields_set and table.stall_axis is None:
            raise ValueError("faults.table.stall_after_s needs faults.table.stall_axis")
        return v

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
