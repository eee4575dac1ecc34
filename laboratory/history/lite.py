"""Indexing a finished run into an SQLite history, and reading a unit's runs back for the
report, with the stdlib ``sqlite3`` (issue 17).

The end of every run indexes it and its report shows the unit's history; on the default
SQLite database this writes exactly the rows and schema the SQLAlchemy store
(``laboratory/history/store.py``) writes, and reads the runs its ``runs_of`` reads, in the
same order, without importing SQLAlchemy (0.2-0.45 s). Other URLs, and `station trend`
and `station history`, go through the store; tests/test_history.py checks that the two
write the same database and read the same runs.
"""

from __future__ import annotations

import sqlite3
from dataclasses import dataclass, field
from pathlib import Path

from laboratory.history.where import HistoryError, run_fields

SQLITE_PREFIX = "sqlite:///"
# the schema as SQLAlchemy's create_all emits it for the store's models on SQLite
TABLES: dict[str, tuple[str, ...]] = {
    "runs": (
        "CREATE TABLE runs (\n\tid INTEGER NOT NULL, \n\trun_uid VARCHAR(64) NOT NULL, \n\t"
        "path VARCHAR(1024) NOT NULL, \n\tlaboratory VARCHAR(32) NOT NULL, \n\t"
        "command VARCHAR(64), \n\tstarted_utc DATETIME NOT NULL, \n\t"
        "date VARCHAR(10) NOT NULL, \n\tstatus VARCHAR(16) NOT NULL, \n\t"
        "verdict VARCHAR(16), \n\tseed INTEGER, \n\tconfig_digest VARCHAR(64), \n\t"
        "PRIMARY KEY (id)\n)",
        "CREATE INDEX ix_runs_started_utc ON runs (started_utc)",
        "CREATE UNIQUE INDEX ix_runs_run_uid ON runs (run_uid)",
    ),
    "run_units": (
        "CREATE TABLE run_units (\n\tid INTEGER NOT NULL, \n\trun_id INTEGER NOT NULL, \n\t"
        "role VARCHAR(64) NOT NULL, \n\tserial VARCHAR(128) NOT NULL, \n\t"
        "PRIMARY KEY (id), \n\t"
        "FOREIGN KEY(run_id) REFERENCES runs (id) ON DELETE CASCADE\n)",
        "CREATE INDEX ix_run_units_run_id ON run_units (run_id)",
        "CREATE INDEX ix_run_units_serial ON run_units (serial)",
    ),
    "results": (
        "CREATE TABLE results (\n\tid INTEGER NOT NULL, \n\trun_id INTEGER NOT NULL, \n\t"
        "\"table\" VARCHAR(64) NOT NULL, \n\tinstrument VARCHAR(64) NOT NULL, \n\t"
        "parameter VARCHAR(64) NOT NULL, \n\tunits VARCHAR(64), \n\testimate FLOAT, \n\t"
        "sigma FLOAT, \n\ttruth FLOAT, \n\tverdict VARCHAR(16), \n\tPRIMARY KEY (id), \n\t"
        "FOREIGN KEY(run_id) REFERENCES runs (id) ON DELETE CASCADE\n)",
        "CREATE INDEX ix_results_run_id ON results (run_id)",
    ),
}
DATETIME_FORMAT = "%Y-%m-%d %H:%M:%S.%f"  # SQLAlchemy's SQLite DATETIME storage


def sqlite_file(url: str) -> Path | None:
    """The file of a plain SQLite URL (``sqlite:///PATH``, no query, not in memory); None
    for any other URL (those go through SQLAlchemy)."""
    if not url.startswith(SQLITE_PREFIX) or "?" in url:
        return None
    path = url.removeprefix(SQLITE_PREFIX)
    return None if path in ("", ":memory:") else Path(path)


def _create_missing(db: sqlite3.Connection) -> None:
    """Each table of the schema that the database lacks, with its indexes (create_all)."""
    have = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
    for name, ddl in TABLES.items():
        if name not in have:
            for statement in ddl:
                db.execute(statement)


def index_run_sqlite(path: Path, run_dir: Path) -> None:
    """Index the finished run in ``run_dir`` into the SQLite file ``path`` (made, with its
    directory and schema, if new), replacing an earlier index of the same run_uid, in one
    transaction; HistoryError naming the database when it cannot be written."""
    f = run_fields(run_dir)
    shown = f"{SQLITE_PREFIX}{path}"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        db = sqlite3.connect(path)
    except (OSError, sqlite3.Error) as e:
        raise HistoryError(f"history database {shown}: {e}") from None
    try:
        with db:
            # one transaction for the schema and the rows: sqlite3 begins one only before
            # the first INSERT, so a new file's nine CREATE statements were each committed
            # and synced alone (issue 17: 20 ms of a first run's end)
            db.execute("BEGIN")
            _create_missing(db)
            for (old,) in db.execute("SELECT id FROM runs WHERE run_uid = ?",
                                     (f.run["run_uid"],)).fetchall():
                db.execute("DELETE FROM run_units WHERE run_id = ?", (old,))
                db.execute("DELETE FROM results WHERE run_id = ?", (old,))
                db.execute("DELETE FROM runs WHERE id = ?", (old,))
            run = {**f.run, "started_utc": f.run["started_utc"].strftime(DATETIME_FORMAT)}
            cols = ", ".join(run)
            marks = ", ".join("?" for _ in run)
            cur = db.execute(f"INSERT INTO runs ({cols}) VALUES ({marks})",
                             tuple(run.values()))
            run_id = cur.lastrowid
            db.executemany("INSERT INTO run_units (run_id, role, serial) VALUES (?, ?, ?)",
                           [(run_id, u["role"], u["serial"]) for u in f.units])
            db.executemany(
                'INSERT INTO results (run_id, "table", instrument, parameter, units, estimate, '
                "sigma, truth, verdict) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                [(run_id, r["table"], r["instrument"], r["parameter"], r["units"],
                  r["estimate"], r["sigma"], r["truth"], r["verdict"]) for r in f.results])
    except (sqlite3.Error, UnicodeDecodeError) as e:  # a damaged file's text too
        raise HistoryError(f"history database {shown}: {e}") from None
    finally:
        db.close()


@dataclass
class LiteResult:
    """A result row as the store's ResultRow holds it."""

    table: str
    instrument: str
    parameter: str
    units: str | None
    estimate: float | None
    sigma: float | None
    truth: float | None
    verdict: str | None


@dataclass
class LiteRun:
    """A run row as the store's RunRow holds it, with its result rows (in their order)."""

    run_uid: str
    path: str
    laboratory: str
    command: str | None
    started_utc: str
    date: str
    status: str
    verdict: str | None
    seed: int | None
    config_digest: str | None
    results: list[LiteResult] = field(default_factory=list)


RUN_COLUMNS = ("id", "run_uid", "path", "laboratory", "command", "started_utc", "date",
               "status", "verdict", "seed", "config_digest")


def runs_of_sqlite(path: Path, unit: str) -> list[LiteRun]:
    """The runs the unit serial ``unit`` took part in, oldest first, as the store's
    ``runs_of`` gives them (by start time, then id; each result in its row order); none
    from a file without the history's tables. HistoryError naming the database when it
    cannot be read; the file is never made or changed."""
    shown = f"{SQLITE_PREFIX}{path}"
    try:
        # read-only, through a URI: the path percent-encoded (a '?', '#' or '%' in a
        # directory's name is a file name's character, not the URI's)
        db = sqlite3.connect(f"{path.absolute().as_uri()}?mode=ro", uri=True)
    except sqlite3.Error as e:
        raise HistoryError(f"history database {shown}: {e}") from None
    try:
        have = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if not set(TABLES) <= have:
            return []
        rows = db.execute(
            f"SELECT DISTINCT {', '.join('runs.' + c for c in RUN_COLUMNS)} FROM runs "
            "JOIN run_units ON runs.id = run_units.run_id WHERE run_units.serial = ? "
            "ORDER BY runs.started_utc, runs.id", (unit,)).fetchall()
        out = []
        for row in rows:
            results = [LiteResult(*r) for r in db.execute(
                'SELECT "table", instrument, parameter, units, estimate, sigma, truth, verdict '
                "FROM results WHERE run_id = ? ORDER BY id", (row[0],))]
            out.append(LiteRun(**dict(zip(RUN_COLUMNS[1:], row[1:], strict=True)),
                               results=results))
        return out
    except (sqlite3.Error, UnicodeDecodeError) as e:  # a damaged file's text too
        raise HistoryError(f"history database {shown}: {e}") from None
    finally:
        db.close()
