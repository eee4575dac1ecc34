"""The calibration history database: every finished run's identity and result rows.

One schema (SQLAlchemy 2.x) on any SQLAlchemy URL: SQLite by default (runs/history.sqlite),
PostgreSQL for a laboratory's shared server. A run is keyed by its run_uid, so indexing it
again replaces its rows (indexing is idempotent). Only the record's files are read.
"""

from __future__ import annotations

import datetime as dt
import json
import math
import os
import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from sqlalchemy import (
    DateTime,
    Float,
    ForeignKey,
    Integer,
    String,
    create_engine,
    select,
)
from sqlalchemy.engine import Engine
from sqlalchemy.exc import ArgumentError, SQLAlchemyError
from sqlalchemy.orm import (
    DeclarativeBase,
    Mapped,
    Session,
    mapped_column,
    relationship,
)

from station.errors import UseError

ENV_URL = "STATION_HISTORY_URL"
DB_NAME = "history.sqlite"
RUNS_DIR = Path("runs")
# the files of a record that hold result rows (one per laboratory; see laboratory/report)
RESULT_FILES = ("results.json", "gyrocompass.json", "esg.json")


class HistoryError(UseError):
    """The history database or a record cannot be used as asked; one line naming it."""


class Base(DeclarativeBase):
    """The history schema's declarative base."""


class RunRow(Base):
    """One finished run: identity from run.json, where its record lies."""

    __tablename__ = "runs"
    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    run_uid: Mapped[str] = mapped_column(String(64), unique=True, index=True)
    path: Mapped[str] = mapped_column(String(1024))
    laboratory: Mapped[str] = mapped_column(String(32))
    command: Mapped[str | None] = mapped_column(String(64))
    started_utc: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), index=True)
    date: Mapped[str] = mapped_column(String(10))  # the UTC date, YYYY-MM-DD
    status: Mapped[str] = mapped_column(String(16))
    verdict: Mapped[str | None] = mapped_column(String(16))
    seed: Mapped[int | None] = mapped_column(Integer)
    config_digest: Mapped[str | None] = mapped_column(String(64))
    units: Mapped[list[UnitRow]] = relationship(back_populates="run", cascade="all, "
                                                "delete-orphan")
    results: Mapped[list[ResultRow]] = relationship(back_populates="run", cascade="all, "
                                                    "delete-orphan")


class UnitRow(Base):
    """One unit serial of a run (role: isu, gyro1, ...; run.json's ``unit``)."""

    __tablename__ = "run_units"
    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), index=True)
    role: Mapped[str] = mapped_column(String(64))
    serial: Mapped[str] = mapped_column(String(128), index=True)
    run: Mapped[RunRow] = relationship(back_populates="units")


class ResultRow(Base):
    """One result row of a run: a constant's estimate and sigma (None: not determined)."""

    __tablename__ = "results"
    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), index=True)
    table: Mapped[str] = mapped_column(String(64))
    instrument: Mapped[str] = mapped_column(String(64))
    parameter: Mapped[str] = mapped_column(String(64))
    units: Mapped[str | None] = mapped_column(String(64))
    estimate: Mapped[float | None] = mapped_column(Float)
    sigma: Mapped[float | None] = mapped_column(Float)
    truth: Mapped[float | None] = mapped_column(Float)
    verdict: Mapped[str | None] = mapped_column(String(16))
    run: Mapped[RunRow] = relationship(back_populates="results")


def default_url() -> str:
    """$STATION_HISTORY_URL, else SQLite at runs/history.sqlite under the current directory."""
    env = os.environ.get(ENV_URL, "").strip()
    return env or sqlite_url(RUNS_DIR / DB_NAME)


def sqlite_url(path: Path) -> str:
    """The SQLAlchemy URL of an SQLite file (absolute, so a URL means one file)."""
    return f"sqlite:///{Path(path).resolve()}"


def open_engine(url: str | None = None) -> Engine:
    """An engine on ``url`` (default: ``default_url()``) with the schema created; an SQLite
    file's directory is made. HistoryError names the URL when it cannot be used."""
    url = url or default_url()
    try:
        if url.startswith("sqlite:///") and url != "sqlite:///:memory:":
            Path(url.removeprefix("sqlite:///")).parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(url)
        Base.metadata.create_all(engine)
    except (ArgumentError, SQLAlchemyError, OSError, ImportError) as e:
        raise HistoryError(f"history database {_shown(url)}: {_first_line(e)}") from None
    return engine


@contextmanager
def session(url: str | None = None) -> Iterator[Session]:
    """A session on the history database, committed when the block ends without error."""
    engine = open_engine(url)
    try:
        with Session(engine) as s:
            try:
                yield s
                s.commit()
            except SQLAlchemyError as e:
                s.rollback()
                raise HistoryError(f"history database {_shown(str(engine.url))}: "
                                   f"{_first_line(e)}") from None
    finally:
        engine.dispose()


def _shown(url: str) -> str:
    """The URL without its password."""
    try:
        from sqlalchemy.engine import make_url

        return make_url(url).render_as_string(hide_password=True)
    except ArgumentError:
        return url


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


def index_run(s: Session, run_dir: Path) -> RunRow:
    """Put one finished run into the history (replacing an earlier index of the same run);
    HistoryError for a directory that holds no finished run."""
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
    earlier = s.scalar(select(RunRow).where(RunRow.run_uid == str(ident["run_uid"])))
    if earlier is not None:  # through the ORM, so its units and results go with it
        s.delete(earlier)
        s.flush()
    verdict = ident.get("verdict")
    run = RunRow(run_uid=str(ident["run_uid"]), path=str(run_dir),
                 laboratory=str(ident.get("laboratory") or "?"), command=ident.get("command"),
                 started_utc=started, date=started.astimezone(dt.UTC).date().isoformat(),
                 status=str(ident["status"]), verdict=None if verdict is None else str(verdict),
                 seed=ident.get("seed") if isinstance(ident.get("seed"), int) else None,
                 config_digest=ident.get("config_digest"))
    unit = ident.get("unit") or {}
    if isinstance(unit, dict):
        run.units = [UnitRow(role=str(k), serial=str(v)) for k, v in unit.items() if v]
    run.results = [
        ResultRow(table=r["table"], instrument=str(r.get("instrument") or ""),
                  parameter=r["parameter"], units=None if r.get("units") is None
                  else str(r["units"]), estimate=_num(r.get("estimate")),
                  sigma=_num(r.get("sigma")), truth=_num(r.get("truth")),
                  verdict=None if r.get("verdict") is None else str(r["verdict"]))
        for r in result_rows(run_dir)]
    s.add(run)
    s.flush()
    return run


def run_dirs(roots: Iterable[Path]) -> list[Path]:
    """Every finished run's directory under ``roots`` (a root that is itself a run counts),
    in path order; HistoryError naming a root that does not exist."""
    found: set[Path] = set()
    for root in roots:
        root = Path(root)
        if not root.is_dir():
            raise HistoryError(f"{root}: no such directory")
        for f in [root / "run.json", *root.rglob("run.json")]:
            if f.is_file() and is_finished(f.parent):
                found.add(f.parent.resolve())
    return sorted(found)


def index_dirs(roots: Iterable[Path], url: str | None = None) -> list[Path]:
    """Index every finished run under ``roots`` into the history at ``url``; the runs."""
    dirs = run_dirs(roots)
    with session(url) as s:
        for d in dirs:
            index_run(s, d)
    return dirs


def runs_of(s: Session, unit: str, since: dt.date | None = None) -> list[RunRow]:
    """The runs a unit serial (of the ISU or any of its instruments) took part in, oldest
    first (optionally from the date ``since`` on)."""
    q = (select(RunRow).join(UnitRow).where(UnitRow.serial == unit)
         .order_by(RunRow.started_utc, RunRow.id).distinct())
    runs = list(s.scalars(q))
    if since is not None:
        runs = [r for r in runs if r.date >= since.isoformat()]
    return runs


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


def index_after(run_dir: Path) -> None:
    """What every run command calls at its end: index the finished run into the history.
    A failure is a warning on stderr, never the run's failure."""
    try:
        if not is_finished(Path(run_dir)):
            return
        url = history_url_for(Path(run_dir))
        if url is None:
            return
        with session(url) as s:
            index_run(s, Path(run_dir))
    except Exception as e:  # noqa: BLE001 - the run's own outcome must come through
        print(f"warning: {run_dir} not indexed in the history: {_first_line(e)}",
              file=sys.stderr)
