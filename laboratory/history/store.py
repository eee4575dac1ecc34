"""The calibration history database: every finished run's identity and result rows.

One schema (SQLAlchemy 2.x) on any SQLAlchemy URL: SQLite by default (runs/history.sqlite),
PostgreSQL for a laboratory's shared server. A run is keyed by its run_uid, so indexing it
again replaces its rows (indexing is idempotent). Only the record's files are read.
"""

from __future__ import annotations

import datetime as dt
import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

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

from laboratory.history.where import (  # noqa: F401 - re-exported: URLs and records
    DB_NAME,
    ENV_URL,
    RESULT_FILES,
    RUNS_DIR,
    HistoryError,
    _first_line,
    default_url,
    history_url_for,
    is_finished,
    result_rows,
    run_fields,
    sqlite_url,
)


# the files of a record that hold result rows (one per laboratory; see laboratory/report)
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


def index_run(s: Session, run_dir: Path) -> RunRow:
    """Put one finished run into the history (replacing an earlier index of the same run);
    HistoryError for a directory that holds no finished run."""
    fields = run_fields(run_dir)
    earlier = s.scalar(select(RunRow).where(RunRow.run_uid == fields.run["run_uid"]))
    if earlier is not None:  # through the ORM, so its units and results go with it
        s.delete(earlier)
        s.flush()
    run = RunRow(**fields.run)
    run.units = [UnitRow(**u) for u in fields.units]
    run.results = [ResultRow(**r) for r in fields.results]
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
