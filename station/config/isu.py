"""Station configuration of the ISU laboratory (TOML -> pydantic): site, truth, noise,
instruments, links and rehearsal faults.

A user file is merged over the embedded default, so it need only name what it changes.
Reading is station.config.file's (one reader for the three laboratories); every mistake
is a one-line ConfigError naming the file and the field, before anything is built.
"""

from __future__ import annotations

import copy
import re
from pathlib import Path
from typing import Annotated

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)

import config as config_pkg
from instruments.faults import TABLE_ONLY_FAULTS, FaultSpec
from instruments.isu.params import (
    AutocollimatorParams,
    BubbleLevelParams,
    IeuParams,
    InstrumentParams,
    SerialParams,
)
from sim.isu.params import (
    AsTuple,
    EnvironmentParams,
    IsuParams,
    OscillatorParams,
    SiteParams,
    TableParams,
    WorldParams,
)
from station.config.alignment import AlignmentSettings
from station.config.calibration import CalibrationOptions
from station.config.file import (
    ConfigError,
    check_depth,
    check_sections,
    read_document,
    read_section,
    validate,
)
from station.config.identity import IsuIdentity
from station.config.limits import IsuLimits
from station.config.plan import PlanSettings
from station.config.strict import STRICT
from station.drivers.isu import SERIAL_INSTRUMENTS

__all__ = ["ConfigError", "StationConfig", "default_dict", "load_config", "read_section"]

MAX_SEED = 2**63 - 1  # the journal stores the seed as a JSON number
_BUS_KEY = re.compile(r"[a-z_][a-z0-9_]*")


class CanLink(BaseModel):
    """python-can settings of the IEU's bus; extra keys go to ``can.Bus`` as given
    (scalars only: a python-can option is a number, a string or a flag)."""

    model_config = ConfigDict(defer_build=True, extra="allow", frozen=True, strict=True)
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

    @model_validator(mode="after")
    def _scalar_options(self) -> CanLink:
        for key, value in (self.model_extra or {}).items():
            if not _BUS_KEY.fullmatch(key):
                raise ValueError(f"links.can: {key!r} is not a python-can option name")
            if not isinstance(value, str | int | float | bool) or value != value:
                raise ValueError(f"links.can.{key}: a python-can option is a number, a "
                                 f"string or a flag, not {type(value).__name__}")
            if isinstance(value, float) and abs(value) == float("inf"):
                raise ValueError(f"links.can.{key}: must be finite")
        return self


class Links(BaseModel):
    model_config = STRICT
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


# ----------------------------------------------------------------------------- instruments
# The instruments' own models (instruments/isu/params.py) name the fields; the bounds a
# configuration must meet are here, as subclasses the rack takes in their place.

ZenithDeg = Annotated[float, Field(ge=0.0, le=180.0)]
AzimuthDeg = Annotated[float, Field(ge=-360.0, le=360.0)]
Aim = Annotated[tuple[AzimuthDeg, ZenithDeg], AsTuple]


class SerialSettings(SerialParams):
    model_config = STRICT
    latency_s: float = Field(ge=0, le=1.0)


class AutocollimatorSettings(AutocollimatorParams):
    model_config = STRICT
    noise_arcsec: float = Field(ge=0, le=60)  # an arcminute: the coarsest of the kind
    fov_deg: float = Field(gt=0, le=5)
    # A MEAS? reply comes after the integration: within the driver's 5 s reply timeout.
    integration_s: float = Field(ge=0, le=2.0)
    zenith_range_deg: Annotated[tuple[ZenithDeg, ZenithDeg], AsTuple]
    initial_aim_deg: Annotated[tuple[Aim, Aim], AsTuple]

    @field_validator("zenith_range_deg")
    @classmethod
    def _range_in_order(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not v[0] < v[1]:
            raise ValueError("the low end must be below the high end")
        return v

    @field_validator("initial_aim_deg")
    @classmethod
    def _aims_within_the_mount(cls, v: tuple[tuple[float, float], ...], info: ValidationInfo
                               ) -> tuple[tuple[float, float], ...]:
        lo, hi = info.data.get("zenith_range_deg", (0.0, 180.0))
        for i, (_, zen) in enumerate(v):
            if not lo <= zen <= hi:
                raise ValueError(f"autocollimator {i + 1} aimed at zenith {zen} deg, outside "
                                 f"zenith_range_deg [{lo}, {hi}]")
        return v


class BubbleLevelSettings(BubbleLevelParams):
    model_config = STRICT
    noise_arcsec: float = Field(ge=0, le=10)  # fifty times a precision level's 0.2
    resolution_arcsec: float = Field(ge=1e-3, le=10)
    range_arcsec: float = Field(gt=0, le=3600)


class IeuSettings(IeuParams):
    model_config = STRICT
    frame_gap_s: float = Field(ge=0, le=0.013)  # a frame at 10 kbit/s, CAN's slowest rate
    max_period_s: float = Field(gt=0, le=3.2)  # 65535 counts of a 20 kHz string


class InstrumentSettings(InstrumentParams):
    model_config = STRICT
    serial: SerialSettings
    autocollimator: AutocollimatorSettings
    bubble_level: BubbleLevelSettings
    ieu: IeuSettings


# ----------------------------------------------------------------------------- faults

# one FaultSpec (instruments.faults) per instrument that can misbehave
FAULT_INSTRUMENTS = (*SERIAL_INSTRUMENTS, "ieu")


def _fault_instrument(name: str) -> str:
    if name not in FAULT_INSTRUMENTS:
        raise ValueError(f"no instrument of that name; known: {', '.join(FAULT_INSTRUMENTS)}")
    return name


# ----------------------------------------------------------------------------- the station


class StationConfig(BaseModel):
    model_config = STRICT
    seed: int = Field(ge=0, le=MAX_SEED)
    site: SiteParams
    environment: EnvironmentParams
    table: TableParams
    isu: IsuParams
    oscillator: OscillatorParams
    instruments: InstrumentSettings
    links: Links
    faults: dict[Annotated[str, AfterValidator(_fault_instrument)], FaultSpec] = {}
    limits: IsuLimits = IsuLimits()  # acceptance limits (station/config/limits.py)
    alignment: AlignmentSettings = AlignmentSettings()  # Part III plan, tape library
    plan: PlanSettings = PlanSettings()  # required accuracies of the day (II-6.2)
    calibration: CalibrationOptions | None = None  # operator options of report 000 Part II
    identity: IsuIdentity

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

    @field_validator("instruments")
    @classmethod
    def _registers_hold_a_sample(cls, v: InstrumentSettings, info: ValidationInfo
                                 ) -> InstrumentSettings:
        """The IEU counts each string in a 16-bit register: over the longest sample period
        the fastest string (at 1.1 g) must count fewer than 65536 cycles."""
        isu = info.data.get("isu")
        if isu is None:
            return v
        f = max(a.fastest_string_hz() for a in isu.accels)
        t = v.ieu.max_period_s
        if f * t >= 65536:
            raise ValueError(
                f"ieu.max_period_s = {t} s would overflow the IEU's 16-bit string registers: "
                f"the fastest accelerometer string runs at {f:.0f} Hz at 1.1 g (at most "
                f"{65535 / f:.3g} s)")
        return v

    @model_validator(mode="after")
    def _alignment_periods_fit_the_ieu(self) -> StationConfig:
        """An alignment's IEU sample period must be one the IEU can be set to."""
        for name in ("level_period_s", "gyro_period_s"):
            per = getattr(self.alignment, name)
            if per > self.instruments.ieu.max_period_s:
                raise ValueError(f"alignment.{name} = {per:g} s is longer than the IEU's "
                                 f"instruments.ieu.max_period_s = "
                                 f"{self.instruments.ieu.max_period_s:g} s")
        return self

    def world_params(self) -> WorldParams:
        """The simulated world's parameters: this config's own parts, validated with it,
        grouped as they are (issue 17: validating them again built the group's schema, 6 ms
        of every run, for nothing)."""
        return WorldParams.model_construct(
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
    """The embedded default configuration as a document."""
    return read_document(config_pkg.path(config_pkg.DEFAULT_CONFIG))


def load_config(
    path: str | Path | None = None, seed: int | None = None, overrides: dict | None = None
) -> StationConfig:
    """The embedded default, with a user TOML file and then ``overrides`` merged over it."""
    data = default_dict()
    source = "the embedded default"
    if path is not None:
        source = str(path)
        doc = read_document(path)
        check_sections(doc, source, "ISU")
        data = _merge(data, doc)
    if overrides:
        check_depth(overrides, "the overrides")
        data = _merge(data, overrides)
        source += " with overrides"
    if seed is not None:
        data["seed"] = seed
    return validate(StationConfig, data, source, "station")
