"""Where a run is indexed and whether it has finished: the history's light half (stdlib
only), so a run's end decides whether to index before any database library is imported."""

from __future__ import annotations

import datetime as dt
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from station.errors import UseError

ENV_URL = "STATION_HISTORY_URL"
DB_NAME = "history.sqlite"
RUNS_DIR = Path("runs")
# the files of a record that hold result rows (one per laboratory; see laboratory/report)
RESULT_FILES = ("results.json", "gyrocompass.json", "esg.json")


class HistoryError(UseError):
    """The history database or a record cannot be used as asked; one line naming it."""


def default_url() -> str:
    """$STATION_HISTORY_URL, else SQLite at runs/history.sqlite under the current directory."""
    env = os.environ.get(ENV_URL, "").strip()
    return env or sqlite_url(RUNS_DIR / DB_NAME)


def sqlite_url(path: Path) -> str:
    """The SQLAlchemy URL of an SQLite file (absolute, so a URL means one file)."""
    return f"sqlite:///{Path(path).resolve()}"


def is_finished(run_dir: Path) -> bool:
    """``run_dir`` holds a run.json whose run has ended (any status but "running")."""
    f = Path(run_dir) / "run.json"
    if not f.is_file():
        return False
    try:
        ident = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(ident, dict) and ident.get("status") not in (None, "running")


def history_url_for(run_dir: Path) -> str | None:
    """Where the end of a run indexes it: $STATION_HISTORY_URL, else history.sqlite in the
    runs directory the run lies under (the nearest ancestor named ``runs``); None when the
    run lies under no runs directory and no URL is set."""
    env = os.environ.get(ENV_URL, "").strip()
    if env:
        return env
    for parent in Path(run_dir).resolve().parents:
        if parent.name == RUNS_DIR.name:
            return sqlite_url(parent / DB_NAME)
    return None


def _first_line(e: BaseException) -> str:
    lines = [x.strip() for x in str(e).splitlines() if x.strip()]
    return lines[0] if lines else type(e).__name__


def _num(v: Any) -> float | None:
    """A finite number from a record's cell, else None."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    return float(v) if math.isfinite(v) else None


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise HistoryError(f"{path}: cannot be read as JSON: {_first_line(e)}") from None


def result_rows(run_dir: Path) -> list[dict[str, Any]]:
    """Every result row of a record: each list of dicts carrying a ``parameter`` in its
    results files (Chart II-5's ``calibration`` for the ISU), and the CIGTF's theta per
    phase, with the list's name."""
    rows = []
    for name in RESULT_FILES:
        f = Path(run_dir) / name
        if not f.is_file():
            continue
        doc = _read_json(f)
        if not isinstance(doc, dict):
            continue
        for table, value in doc.items():
            if not isinstance(value, list):
                continue
            for r in value:
                if isinstance(r, dict) and isinstance(r.get("parameter"), str):
                    rows.append({"table": table, **r})
                elif table == "phases" and isinstance(r, dict) and "theta_arcsec" in r:
                    # the CIGTF's gyrocompassing error per phase (report 001, eqs. 20-25)
                    rows.append({"table": table, "instrument": r.get("phase"),
                                 "parameter": "theta", "units": "arcsec",
                                 "estimate": r.get("theta_arcsec"),
                                 "sigma": r.get("sigma_arcsec"), "verdict": r.get("verdict")})
    return rows


def _started(ident: dict, path: Path) -> dt.datetime:
    try:
        t = dt.datetime.fromisoformat(str(ident["started_utc"]))
    except (KeyError, ValueError):
        raise HistoryError(f"{path}: started_utc missing or not an ISO time") from None
    return t if t.tzinfo else t.replace(tzinfo=dt.UTC)


@dataclass
class RunFields:
    """One finished run as the history's rows hold it: the columns of its ``runs`` row,
    of each ``run_units`` row and of each ``results`` row (ids and run_id aside)."""

    run: dict[str, Any]
    units: list[dict[str, Any]]
    results: list[dict[str, Any]]


def run_fields(run_dir: Path) -> RunFields:
    """What indexing the record in ``run_dir`` puts into the history (the one reading of a
    record, for the SQLAlchemy store and the stdlib SQLite writer alike); HistoryError for a
    directory that holds no finished run."""
    run_dir = Path(run_dir).resolve()
    f = run_dir / "run.json"
    if not f.is_file():
        raise HistoryError(f"{run_dir}: no run.json, not a run's record")
    ident = _read_json(f)
    if not isinstance(ident, dict) or not ident.get("run_uid"):
        raise HistoryError(f"{f}: run_uid missing")
    if ident.get("status") in (None, "running"):
        raise HistoryError(f"{f}: status {ident.get('status')!r}: the run has not finished")
    started = _started(ident, f)
    verdict = ident.get("verdict")
    run = {"run_uid": str(ident["run_uid"]), "path": str(run_dir),
           "laboratory": str(ident.get("laboratory") or "?"), "command": ident.get("command"),
           "started_utc": started, "date": started.astimezone(dt.UTC).date().isoformat(),
           "status": str(ident["status"]), "verdict": None if verdict is None else str(verdict),
           "seed": ident.get("seed") if isinstance(ident.get("seed"), int) else None,
           "config_digest": ident.get("config_digest")}
    unit = ident.get("unit") or {}
    units = ([{"role": str(k), "serial": str(v)} for k, v in unit.items() if v]
             if isinstance(unit, dict) else [])
    results = [{"table": r["table"], "instrument": str(r.get("instrument") or ""),
                "parameter": r["parameter"],
                "units": None if r.get("units") is None else str(r["units"]),
                "estimate": _num(r.get("estimate")), "sigma": _num(r.get("sigma")),
                "truth": _num(r.get("truth")),
                "verdict": None if r.get("verdict") is None else str(r["verdict"])}
               for r in result_rows(run_dir)]
    return RunFields(run, units, results)
