"""The check-sheet as data (every laboratory's Laboratory Procedures Sheets) and the base
of each laboratory's own sheets (procedures/isu/sheets.py): what a run records and what
reports render from. Lab units at this boundary.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field


class Sheet(BaseModel):
    """A sheet of the record: plain data, no unknown fields."""

    model_config = ConfigDict(defer_build=True, extra="forbid")


class SheetHeader(Sheet):
    """The heading of a chart's sheet (Experiment, Principal Operator, Date, Identification,
    the "... Sheet Used" cross-references, Special Procedures), filled from the run's
    identity; None on records made before headers existed."""

    experiment: str
    principal_operator: str
    date: str  # UTC date the run started, ISO 8601
    identification: str  # the unit under test's serial number
    sheets_used: list[str] = Field(default_factory=list)  # chart names, e.g. "Chart I-3"
    special_procedures: str | None = None


class StepRecord(Sheet):
    number: str
    text: str
    done: bool
    t_sim: float
    reading: Any = None


class CheckSheet(Sheet):
    """A Laboratory Procedures Sheet with its ticks (steps numbered as the chart)."""

    chart: str
    title: str
    steps: list[StepRecord] = Field(default_factory=list)
    header: SheetHeader | None = None


SHEET_MODELS: dict[str, type[Sheet]] = {"check": CheckSheet}  # every check_<chart> sheet
