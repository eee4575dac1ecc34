"""The ``[identity]`` section of every laboratory's configuration: which station this is
and the serial numbers of the unit under test, as the run's record (run.json) and the
sheet headers' Identification give them. Validated like the other sections.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, StringConstraints

from station.config.file import check_sections, read_document, validate

_STRICT = ConfigDict(defer_build=True, extra="forbid", frozen=True, strict=True)
# a serial number or station id: printable ASCII, one line, at most 64 characters
Serial = Annotated[str, StringConstraints(min_length=1, max_length=64,
                                          pattern=r"^[ -~]+$", strip_whitespace=True)]


class IsuUnit(BaseModel):
    """The ISU (report 000) and its six instruments."""

    model_config = _STRICT
    isu: Serial
    gyro1: Serial
    gyro2: Serial
    gyro3: Serial
    accel1: Serial
    accel2: Serial
    accel3: Serial


class IsuIdentity(BaseModel):
    model_config = _STRICT
    station_id: Serial
    unit: IsuUnit
    # how old an earlier run's sheets may be to be carried forward (`--prior`, `--survey`)
    max_prior_age_days: float = Field(default=30.0, gt=0.0, le=3650.0)


class CigtfUnit(BaseModel):
    """The single-degree-of-freedom gyro under test (report 001)."""

    model_config = _STRICT
    gyro: Serial = "SDF-GYRO-001"


class CigtfIdentity(BaseModel):
    model_config = _STRICT
    station_id: Serial = "CIGTF-1"
    unit: CigtfUnit = CigtfUnit()


class EsgUnit(BaseModel):
    """The electrostatic gyro's rotor (report 004)."""

    model_config = _STRICT
    rotor: Serial = "ESG-ROTOR-001"


class EsgIdentity(BaseModel):
    model_config = _STRICT
    station_id: Serial = "ESG-LAB-1"
    unit: EsgUnit = EsgUnit()


def load_identity(path: str | Path | None, lab: str) -> CigtfIdentity | EsgIdentity:
    """The ``[identity]`` of a CIGTF or ESG file (``lab`` "CIGTF" or "ESG"); the defaults
    when there is no file or no such section. (The ISU's is a field of StationConfig.)"""
    model: type[CigtfIdentity] | type[EsgIdentity] = (
        CigtfIdentity if lab == "CIGTF" else EsgIdentity)
    if path is None:
        return model()
    where = str(path)
    doc = read_document(path)
    check_sections(doc, where, lab)
    return validate(model, doc.get("identity", {}), where, lab, ("identity",))
