"""The report's "History of this unit": the trend of the run's unit over this run and its
predecessors in the calibration history (never later runs), as `station trend` shows it,
with each constant's trend as an inline SVG sparkline (no plotting library on the report's
path). Any failure is the section's one line, never the report's."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from laboratory.history.sparkline import sparkline
from laboratory.history.trend import (
    COLUMNS,
    DEFAULT_LEVEL,
    RunLike,
    Trend,
    cells,
    flags,
    trends,
    z_limit,
)
from laboratory.history.where import history_url_for


def _unit_of(ident: dict) -> str | None:
    """The unit a run's history follows: the ISU's serial, else the run's one unit."""
    unit = ident.get("unit")
    if not isinstance(unit, dict) or not unit:
        return None
    serial = unit.get("isu") or next(iter(unit.values()))
    return str(serial) if serial else None


def _none(text: str) -> dict[str, Any]:
    return {"shown": False, "text": text}


def history_section(run_dir: Path, url: str | None = None,
                    level: float = DEFAULT_LEVEL) -> dict[str, Any]:
    """The section of the run in ``run_dir`` from the history at ``url`` (default: where
    the run was indexed at its end): ``shown`` with unit, text, columns and rows (each
    with its sparkline); or not shown, with the one line saying why."""
    try:
        ident = json.loads((Path(run_dir) / "run.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return _none("No history: the record has no readable run.json (no run identity).")
    unit = _unit_of(ident) if isinstance(ident, dict) else None
    if unit is None or not ident.get("run_uid"):
        return _none("No history: run.json names no unit or run_uid.")
    url = url or history_url_for(Path(run_dir))
    if url is None:
        return _none("No history: the calibration history is off for this run (it lies "
                     "under no runs directory and $STATION_HISTORY_URL is unset).")
    lab = ident.get("laboratory")
    runs = [r for r in _runs_of(url, unit) if r.laboratory == lab]
    uids = [r.run_uid for r in runs]
    if ident["run_uid"] not in uids:
        return _none(f"No history: this run is not in the calibration history of {unit} "
                     "(it was not indexed).")
    upto = runs[:uids.index(ident["run_uid"]) + 1]
    if len(upto) == 1:
        return _none(f"No earlier runs of {unit} in the calibration history: this is "
                     "its first; nothing to trend yet.")
    ts = trends(upto, level)
    if not ts:
        return _none(f"No constant of {unit} determined on two or more completed runs up to "
                     f"this one ({len(upto)} runs in the history): nothing to trend yet.")
    return shown(ts, unit, level, f"{len(upto)} runs of {unit} in the {lab} laboratory's "
                 "history up to and including this one", "this run")


def _runs_of(url: str, unit: str) -> Sequence[RunLike]:
    """The unit's runs, oldest first: from a plain SQLite file with the stdlib
    (laboratory.history.lite), from any other URL through the store (SQLAlchemy)."""
    from laboratory.history.lite import runs_of_sqlite, sqlite_file

    db = sqlite_file(url)
    if db is not None:
        return runs_of_sqlite(db, unit) if db.is_file() else []
    from laboratory.history.store import runs_of, session

    with session(url) as s:
        return runs_of(s, unit)


def shown(ts: list[Trend], unit: str, level: float, where: str,
          last: str = "the latest") -> dict[str, Any]:
    """The section for the trends ``ts`` of ``unit`` (``where`` says which runs they
    cover): one row per constant as `station trend` prints it, with its sparkline (SVG
    markup; its last point is ``last``)."""
    rows: list[dict[str, Any]] = [{"label": t.name, "cells": cells(t),
                                   "flagged": bool(flags(t)), "spark": sparkline(t, last)}
                                  for t in ts]
    return {"shown": True, "unit": unit, "level": level, "z_limit": z_limit(level),
            "columns": list(COLUMNS), "rows": rows,
            "text": f"{where}; {sum(bool(flags(t)) for t in ts)} of {len(ts)} constants "
                    f"flagged at the {level:g} level."}


def safe_history_section(run_dir: Path, url: str | None = None) -> dict[str, Any]:
    """``history_section``, with any failure (a database that cannot be opened, a record
    that cannot be read) turned into the section's one line."""
    try:
        return history_section(run_dir, url)
    except Exception as e:  # noqa: BLE001 - the report never fails because of the history
        first = next((x.strip() for x in str(e).splitlines() if x.strip()), type(e).__name__)
        return _none(f"No history: the calibration history cannot be read: {first}")
