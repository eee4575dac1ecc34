"""The stdlib SQLite writer of the history (laboratory/history/lite.py, issue 17) writes the
database the SQLAlchemy store writes, and a run's end indexes without importing SQLAlchemy."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

from laboratory.history.lite import index_run_sqlite, sqlite_file
from laboratory.history.store import RunRow, index_run, session, sqlite_url

ROOT = Path(__file__).resolve().parents[1]


def record(d: Path, uid: str, started: str, estimate: float) -> Path:
    """A finished run's record as the history reads it: run.json and results.json."""
    d.mkdir(parents=True)
    (d / "run.json").write_text(json.dumps({
        "run_uid": uid, "laboratory": "isu", "command": "day", "started_utc": started,
        "status": "completed", "verdict": "PASS", "seed": 7, "config_digest": "ab" * 32,
        "unit": {"isu": "ISU-1", "gyro1": "G-1", "gyro2": ""}}))
    (d / "results.json").write_text(json.dumps({"calibration": [
        {"instrument": "gyro1", "parameter": "R", "units": "deg/hr", "estimate": estimate,
         "sigma": 0.01, "truth": 1.12, "verdict": "PASS"},
        {"instrument": "gyro1", "parameter": "B_I", "units": None, "estimate": float("nan"),
         "sigma": None, "truth": True, "verdict": None}], "notes": "x"}))
    return d


def dump(path: Path) -> list[str]:
    """The database's schema and rows (sorted: SQLAlchemy creates indexes in set order)."""
    db = sqlite3.connect(path)
    try:
        return sorted(db.iterdump())
    finally:
        db.close()


def test_both_writers_make_the_same_database(tmp_path: Path) -> None:
    runs = [record(tmp_path / "a", "u1", "2026-01-02T03:04:05.678+00:00", 1.1),
            record(tmp_path / "b", "u2", "2026-01-03T03:04:05", 1.2),
            record(tmp_path / "c", "u3", "2026-01-04T01:00:00+02:00", 1.3)]
    order = [runs[0], runs[1], runs[0], runs[2]]  # u1 indexed again: replaced
    for d in order:
        with session(sqlite_url(tmp_path / "orm.sqlite")) as s:
            index_run(s, d)
        index_run_sqlite(tmp_path / "std.sqlite", d)
    assert dump(tmp_path / "std.sqlite") == dump(tmp_path / "orm.sqlite")
    with session(sqlite_url(tmp_path / "std.sqlite")) as s:  # read back through the store
        got = [(r.run_uid, r.date, len(r.units), [x.estimate for x in r.results])
               for r in s.query(RunRow).order_by(RunRow.id)]
    assert got == [("u2", "2026-01-03", 2, [1.2, None]), ("u1", "2026-01-02", 2, [1.1, None]),
                   ("u3", "2026-01-03", 2, [1.3, None])]


def test_each_writes_into_the_others_database(tmp_path: Path) -> None:
    a = record(tmp_path / "a", "u1", "2026-01-02T03:04:05+00:00", 1.1)
    b = record(tmp_path / "b", "u2", "2026-01-03T03:04:05+00:00", 1.2)
    with session(sqlite_url(tmp_path / "x.sqlite")) as s:
        index_run(s, a)
    index_run_sqlite(tmp_path / "x.sqlite", b)
    index_run_sqlite(tmp_path / "y.sqlite", a)
    with session(sqlite_url(tmp_path / "y.sqlite")) as s:
        index_run(s, b)
    assert dump(tmp_path / "x.sqlite") == dump(tmp_path / "y.sqlite")


def test_only_plain_sqlite_files_go_to_the_stdlib() -> None:
    assert sqlite_file("sqlite:////tmp/h.sqlite") == Path("/tmp/h.sqlite")
    assert sqlite_file("sqlite:///:memory:") is None
    assert sqlite_file("sqlite:////tmp/h.sqlite?mode=ro") is None
    assert sqlite_file("postgresql+psycopg://h/db") is None


def test_a_runs_end_indexes_without_sqlalchemy(tmp_path: Path) -> None:
    d = record(tmp_path / "runs" / "day" / "one", "u1", "2026-01-02T03:04:05+00:00", 1.1)
    code = ("import sys; from pathlib import Path; from laboratory.history import index_after; "
            f"index_after(Path({str(d)!r})); "
            "print([m for m in sys.modules if m.split('.')[0] in ('sqlalchemy', 'scipy')])")
    env = {k: v for k, v in os.environ.items() if k != "STATION_HISTORY_URL"}
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                       env={**env, "PYTHONPATH": str(ROOT)}, check=True)
    assert p.stdout.strip() == "[]" and p.stderr == ""
    with session(sqlite_url(tmp_path / "runs" / "history.sqlite")) as s:
        assert [r.run_uid for r in s.query(RunRow)] == ["u1"]


def test_both_readers_give_the_same_runs_and_trends(tmp_path: Path) -> None:
    """runs_of_sqlite reads what the store's runs_of reads (the runs of a unit by its
    serial, oldest first, ties by id, a run once however many of its units match, each
    run's results in their order), and the trends of both are equal; a file without the
    history's tables gives none, and is left as it was."""
    import random

    from laboratory.history.lite import runs_of_sqlite
    from laboratory.history.store import runs_of
    from laboratory.history.trend import trends

    rng = random.Random(17)
    db = tmp_path / "h.sqlite"
    for i in range(8):  # out of date order, two at the same instant, one indexed twice
        day = rng.choice(["2026-01-02", "2026-01-05", "2026-01-03"])
        d = record(tmp_path / f"r{i}", f"u{i}", f"{day}T03:04:05+00:00",
                   1.1 + rng.gauss(0.0, 0.01))
        index_run_sqlite(db, d)
    index_run_sqlite(db, tmp_path / "r2")
    for unit in ("ISU-1", "G-1", "NONE"):
        lite = runs_of_sqlite(db, unit)
        with session(sqlite_url(db)) as s:
            orm = runs_of(s, unit)
            want = [(r.run_uid, r.path, r.laboratory, r.date, r.status,
                     [(x.table, x.instrument, x.parameter, x.units, x.estimate, x.sigma)
                      for x in r.results]) for r in orm]
            t_orm = trends(orm)
        got = [(r.run_uid, r.path, r.laboratory, r.date, r.status,
                [(x.table, x.instrument, x.parameter, x.units, x.estimate, x.sigma)
                 for x in r.results]) for r in lite]
        assert got == want and (len(got) == 8 or unit == "NONE")
        assert trends(lite) == t_orm
    empty = tmp_path / "empty.sqlite"
    sqlite3.connect(empty).close()
    assert runs_of_sqlite(empty, "ISU-1") == [] and empty.stat().st_size == 0
    odd = tmp_path / "lab #1?a=b %20 x" / "h.sqlite"  # URI characters in a directory's name
    odd.parent.mkdir()
    odd.write_bytes(db.read_bytes())
    assert [r.run_uid for r in runs_of_sqlite(odd, "ISU-1")] == [
        r.run_uid for r in runs_of_sqlite(db, "ISU-1")]


def test_a_reports_history_needs_neither_sqlalchemy_nor_scipy(tmp_path: Path) -> None:
    """The report's history section of a run in a runs directory reads its SQLite file with
    the stdlib and computes its levels without scipy, and shows it."""
    runs = [record(tmp_path / "runs" / "day" / f"r{i}", f"u{i}",
                   f"2026-01-0{i + 1}T03:04:05+00:00", 1.1 + 0.001 * i) for i in range(3)]
    for d in runs:
        index_run_sqlite(tmp_path / "runs" / "history.sqlite", d)
    code = ("import sys; from pathlib import Path; "
            "from laboratory.history.section import safe_history_section; "
            f"s = safe_history_section(Path({str(runs[-1])!r})); print(s['shown'], s['text']); "
            "print(sorted({m for m in sys.modules "
            "if m.split('.')[0] in ('sqlalchemy', 'scipy')}))")
    env = {k: v for k, v in os.environ.items() if k != "STATION_HISTORY_URL"}
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                       env={**env, "PYTHONPATH": str(ROOT)}, check=True)
    shown, modules = p.stdout.strip().splitlines()
    assert shown.startswith("True 3 runs of ISU-1") and modules == "[]", p.stdout


def test_the_trends_levels_are_scipys_without_scipy() -> None:
    """chi2_sf and z_limit (the history's p-values and change limit, computed without
    importing scipy) agree with scipy.special's chdtrc and ndtri (what scipy.stats.chi2.sf
    and norm.ppf compute) over random degrees of freedom and statistics, from the centre
    to far tails, and at the edges."""
    import math
    import random

    from scipy.special import chdtrc, ndtri

    from laboratory.history.trend import chi2_sf, z_limit

    rng = random.Random(5)
    for _ in range(3000):
        dof = rng.choice([rng.randint(1, 12), rng.randint(1, 3000)])
        x = rng.uniform(0.0, 3.0 * dof + 20.0)
        want = float(chdtrc(dof, x))
        assert math.isclose(chi2_sf(x, dof), want, rel_tol=2e-11, abs_tol=1e-300), (dof, x)
    for x, dof, want in ((0.0, 1, 1.0), (-1.0, 4, 1.0), (math.inf, 3, 0.0), (1e5, 3, 0.0)):
        assert chi2_sf(x, dof) == want
    assert math.isnan(chi2_sf(math.nan, 2))
    for level in (0.5, 0.9, 0.95, 0.99, 0.999, 0.9999, 1.0 - 1e-12):
        assert math.isclose(z_limit(level), float(ndtri(0.5 + level / 2.0)), rel_tol=1e-15)


def test_a_damaged_history_is_an_error_naming_it(tmp_path: Path) -> None:
    """A history file whose text is damaged: the reader and the writer raise HistoryError
    naming the database (the report's section and the run's index then say so in their
    one line), not a UnicodeDecodeError, and nothing is read from it."""
    import pytest

    from laboratory.history.lite import runs_of_sqlite
    from laboratory.history.where import HistoryError

    db = tmp_path / "h.sqlite"
    for i in range(3):
        index_run_sqlite(db, record(tmp_path / f"r{i}", f"u{i}", "2026-01-02T03:04:05+00:00",
                                    1.1))
    good = db.read_bytes()
    for needle, at in ((b"deg/hr", 0), (b"tableresultsresults", 5)):  # a row's units; a
        raw = bytearray(good)  # table's name in the schema's own table (the writer reads it)
        i = raw.find(needle)
        assert i > 0
        raw[i + at:i + at + 2] = b"\xff\xff"
        db.write_bytes(bytes(raw))
        with pytest.raises(HistoryError, match=f"history database sqlite:///{db}"):
            runs_of_sqlite(db, "ISU-1")
    with pytest.raises(HistoryError, match=f"history database sqlite:///{db}"):
        index_run_sqlite(db, record(tmp_path / "r9", "u9", "2026-01-02T03:04:05+00:00", 1.1))


def test_an_index_that_fails_leaves_no_part_of_its_schema(tmp_path: Path) -> None:
    """The schema and the rows are one transaction: a database whose runs table the run
    cannot go into (another schema) gets neither the missing tables nor any row; the same
    run then goes into a good database whole."""
    from laboratory.history.where import HistoryError

    run = record(tmp_path / "a", "u1", "2026-01-02T03:04:05", 1.1)
    bad = tmp_path / "bad.sqlite"
    db = sqlite3.connect(bad)
    db.execute("CREATE TABLE runs (id INTEGER PRIMARY KEY, other TEXT)")
    db.commit()
    db.close()
    try:
        index_run_sqlite(bad, run)
    except HistoryError as e:
        assert str(bad) in str(e)
    else:
        raise AssertionError("indexed into a runs table without its columns")
    assert dump(bad) == ["BEGIN TRANSACTION;", "COMMIT;",
                         "CREATE TABLE runs (id INTEGER PRIMARY KEY, other TEXT);"]
    index_run_sqlite(tmp_path / "good.sqlite", run)
    good = sqlite3.connect(tmp_path / "good.sqlite")
    try:
        assert good.execute("SELECT count(*) FROM results").fetchone() == (2,)
        assert {r[0] for r in good.execute("SELECT name FROM sqlite_master")} >= {
            "runs", "run_units", "results", "ix_runs_run_uid"}
    finally:
        good.close()
