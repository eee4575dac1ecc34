"""The check-sheet as data (every laboratory's Laboratory Procedures Sheets) and the base
of each laboratory's own sheets (procedures/isu/sheets.py): what a run records and what
reports render from. Lab units at this boundary.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field


class Sheet(BaseModel):
    """A sheet of the record: plain data, no unknown fields."""

    model_config = ConfigDict(extra="forbid")


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


SHEET_MODELS: dict[str, type[Sheet]] = {"check": CheckSheet}  # every check_<chart> sheet
