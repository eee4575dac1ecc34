"""The calibration history (laboratory/history): runs indexed at their end and on demand,
a unit's runs listed, and trends that flag a 5-sigma change of one constant and nothing in
five days of the same unit, on SQLite and on a real PostgreSQL server."""

from __future__ import annotations

import glob
import json
import math
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import tomllib
from collections.abc import Iterator
from pathlib import Path

import pytest

from laboratory.identity import to_toml

ROOT = Path(__file__).resolve().parent.parent
DAY = ["day", "--only", "II-6", "--only", "II-11", "--quiet"]  # gyro constants, ~3 s
SHIFT_Z = 5.0  # the shifted day's gyro1 R moves by 5 combined sigmas of a change


def station(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """`station ARGS` in a subprocess from the source tree."""
    e = dict(os.environ)
    e.pop("STATION_HISTORY_URL", None)
    e.update(env or {})
    return subprocess.run([sys.executable, "-m", "laboratory.cli", *args], cwd=ROOT, env=e,
                          capture_output=True, text=True, timeout=300)


def r_row(run: Path) -> dict:
    rows = json.loads((run / "results.json").read_text())["calibration"]
    return next(r for r in rows if r["instrument"] == "gyro1" and r["parameter"] == "R")


@pytest.fixture(scope="module")
def days(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Five days of the same unit (same config, seeds 1-5), each indexed into an SQLite
    history at its end, then a sixth (seed 6) whose config shifts gyro1 R."""
    base = tmp_path_factory.mktemp("history")
    db = base / "end.sqlite"
    env = {"STATION_HISTORY_URL": f"sqlite:///{db}"}
    runs = []
    for seed in range(1, 6):
        out = base / f"day{seed}"
        p = station(*DAY, "--seed", str(seed), "--out", str(out), env=env)
        assert p.returncode == 0, p.stderr
        assert "warning" not in p.stderr, p.stderr
        runs.append(out)
    cfg = tomllib.loads((runs[0] / "config.toml").read_text())
    sigma = r_row(runs[-1])["sigma"]
    shift = SHIFT_Z * math.sqrt(2.0) * sigma
    cfg["isu"]["gyros"][0]["R_deg_hr"] += shift
    shifted_cfg = base / "shifted.toml"
    shifted_cfg.write_text(to_toml(cfg))
    out = base / "shifted"
    p = station(*DAY, "--seed", "6", "--config", str(shifted_cfg), "--out", str(out), env=env)
    assert p.returncode == 0, p.stderr
    assert "warning" not in p.stderr, p.stderr  # indexed at its end, as the five
    return {"base": base, "db": db, "runs": runs, "shifted": out, "shift": shift,
            "sigma": sigma}


def test_each_run_is_indexed_at_its_end(days: dict) -> None:
    # wide enough for one table: a record path folded across lines is no test of the index
    p = station("history", "GYRO-001", "--db", str(days["db"]), env={"COLUMNS": "300"})
    assert p.returncode == 0, p.stderr
    for run in [*days["runs"], days["shifted"]]:
        assert str(run) in p.stdout, f"{run} not listed:\n{p.stdout}"
    assert p.stdout.count("completed") == 6
    # the ISU's serial finds the same runs; an unknown unit is one line, exit 2
    q = station("history", "ISU-000-001", "--db", str(days["db"]))
    assert q.returncode == 0 and q.stdout.count("completed") == 6
    bad = station("history", "NO-SUCH-UNIT", "--db", str(days["db"]))
    assert bad.returncode == 2 and bad.stderr.startswith("error: history: no runs of unit")


def test_five_days_of_the_same_unit_flag_nothing(days: dict, tmp_path: Path) -> None:
    db = tmp_path / "five.sqlite"
    p = station("history", "index", *map(str, days["runs"]), "--db", str(db))
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == "indexed 5 run(s)"
    png = tmp_path / "trend.png"
    t = station("trend", "ISU-000-001", "--level", "0.999", "--db", str(db),
                "--plot", str(png))
    assert t.returncode == 0, t.stdout + t.stderr
    assert "flagged" not in t.stdout
    assert png.stat().st_size > 10_000


def _check_shift_flagged(days: dict, url: str, png: Path) -> None:
    t = station("trend", "ISU-000-001", "--db", url, "--plot", str(png))
    assert t.returncode == 1, t.stdout + t.stderr
    flagged = [x for x in t.stdout.splitlines() if x.startswith("flagged:")]
    assert flagged and all(x.startswith("flagged: gyro1 R ") for x in flagged), flagged
    change = next(x for x in flagged if "changed by" in x)
    assert str(days["shifted"]) in change
    # the change seen is the shift within its combined sigma's few multiples
    delta = float(change.split("changed by ")[1].split()[0])
    assert abs(delta - days["shift"]) < 4 * math.sqrt(2.0) * days["sigma"]


def test_a_five_sigma_shift_of_gyro1_r_is_flagged(days: dict, tmp_path: Path) -> None:
    _check_shift_flagged(days, str(days["db"]), tmp_path / "trend.png")
    # --since after every run leaves nothing to trend: one line, exit 2
    p = station("trend", "ISU-000-001", "--db", str(days["db"]), "--since", "2999-01-01",
                "--plot", str(tmp_path / "x.png"))
    assert p.returncode == 2 and "no constant determined" in p.stderr


def test_indexing_again_replaces_the_run(days: dict) -> None:
    from laboratory.history.store import ResultRow, RunRow, index_dirs, session, sqlite_url

    url = sqlite_url(days["db"])
    assert len(index_dirs([days["base"]], url)) == 6
    with session(url) as s:
        assert s.query(RunRow).count() == 6
        n = s.query(ResultRow).count()
    index_dirs([days["runs"][0]], url)
    with session(url) as s:
        assert s.query(RunRow).count() == 6 and s.query(ResultRow).count() == n


def test_refusals_are_one_line(tmp_path: Path) -> None:
    p = station("history", "index", str(tmp_path / "nothing"), "--db", str(tmp_path / "h.db"))
    assert p.returncode == 2 and p.stderr.strip().endswith("nothing: no such directory")
    p = station("trend", "X", "--level", "1.5", "--db", str(tmp_path / "h.db"))
    assert p.returncode == 2 and "--level" in p.stderr and len(p.stderr.splitlines()) == 1
    p = station("history", "X", "--db", "nosuchdialect://x")
    assert p.returncode == 2 and p.stderr.startswith("error: history database")


def test_a_run_outside_a_runs_directory_is_not_indexed_without_a_url(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from laboratory.history.store import history_url_for

    monkeypatch.delenv("STATION_HISTORY_URL", raising=False)
    assert history_url_for(tmp_path / "x") is None
    assert history_url_for(tmp_path / "runs" / "day" / "x") == \
        f"sqlite:///{(tmp_path / 'runs' / 'history.sqlite').resolve()}"
    monkeypatch.setenv("STATION_HISTORY_URL", "postgresql+psycopg://h/db")
    assert history_url_for(tmp_path / "x") == "postgresql+psycopg://h/db"


def test_a_history_that_cannot_be_written_is_a_warning_not_the_runs_failure(
        tmp_path: Path) -> None:
    out = tmp_path / "day"
    p = station(*DAY, "--positions", "1", "--seed", "1", "--out", str(out),
                env={"STATION_HISTORY_URL": "nosuchdialect://x"})
    assert p.returncode == 0, p.stderr
    assert p.stderr.strip() == f"warning: {out} not indexed in the history: history " \
        "database nosuchdialect://x: Can't load plugin: sqlalchemy.dialects:nosuchdialect"
    assert json.loads((out / "run.json").read_text())["status"] == "completed"


def test_the_cigtf_theta_per_phase_is_indexed(tmp_path: Path) -> None:
    """A CIGTF run is indexed at its end under its runs directory (no URL set): theta per
    phase and what the pre-test set-up left (b, c, a + d)."""
    out = tmp_path / "runs" / "cigtf" / "one"
    p = station("gyrocompass-test", "--out", str(out))
    assert p.returncode == 0, p.stderr
    from laboratory.history.store import RunRow, session, sqlite_url

    with session(sqlite_url(tmp_path / "runs" / "history.sqlite")) as s:
        (run,) = s.query(RunRow).all()
        phases = json.loads((out / "gyrocompass.json").read_text())["phases"]
        assert run.laboratory == "cigtf" and run.status == "completed"
        setup = json.loads((out / "gyrocompass.json").read_text())["setup"]
        assert [(r.instrument, r.parameter, r.estimate, r.sigma) for r in run.results] == [
            (ph["phase"], "theta", ph["theta_arcsec"], ph["sigma_arcsec"]) for ph in phases] + [
            ("set-up", r["parameter"], r["estimate"], r["sigma"]) for r in setup]


# ------------------------------------------------------------------------- PostgreSQL


def _pg_bin(name: str) -> str | None:
    found = shutil.which(name)
    if found:
        return found
    debian = sorted(glob.glob(f"/usr/lib/postgresql/*/bin/{name}"))
    return debian[-1] if debian else None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="module")
def postgres() -> Iterator[str]:
    """A PostgreSQL cluster of our own in a temporary directory on 127.0.0.1 (initdb and
    pg_ctl from Debian's postgresql package; as the postgres user when run as root)."""
    initdb, pg_ctl = _pg_bin("initdb"), _pg_bin("pg_ctl")
    if initdb is None or pg_ctl is None:
        pytest.skip("PostgreSQL's initdb/pg_ctl are not installed (Debian: apt-get install "
                    "postgresql; .ci/run does so)")
    pytest.importorskip("psycopg", reason="psycopg (v3) is not installed (pip install "
                        "'psycopg[binary]')")
    as_user: list[str] = []
    d = Path(tempfile.mkdtemp(prefix="station-pg-"))
    if os.geteuid() == 0:  # initdb refuses root
        runuser = shutil.which("runuser")
        if runuser is None:
            pytest.skip("running as root and no runuser to start PostgreSQL as postgres")
        as_user = [runuser, "-u", "postgres", "--"]
        shutil.chown(d, "postgres")
    data, port = d / "data", _free_port()
    subprocess.run([*as_user, initdb, "-D", str(data), "-U", "station", "-A", "trust",
                    "--no-sync"], check=True, capture_output=True, timeout=120)
    subprocess.run([*as_user, pg_ctl, "-D", str(data), "-l", str(d / "log"), "-w", "-o",
                    f"-p {port} -c listen_addresses=127.0.0.1 -k {d} -c fsync=off",
                    "start"], check=True, capture_output=True, timeout=120)
    try:
        url = f"postgresql+psycopg://station@127.0.0.1:{port}/postgres"
        from sqlalchemy import create_engine, text

        for _ in range(50):  # pg_ctl -w waited; a first connection may still race
            try:
                with create_engine(url).connect() as c:
                    c.execute(text("select 1"))
                break
            except Exception:  # noqa: BLE001
                time.sleep(0.1)
        yield url
    finally:
        subprocess.run([*as_user, pg_ctl, "-D", str(data), "-m", "immediate", "stop"],
                       capture_output=True, timeout=120)
        shutil.rmtree(d, ignore_errors=True)


def test_history_on_postgresql(days: dict, postgres: str, tmp_path: Path) -> None:
    p = station("history", "index", str(days["base"]), "--db", postgres)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == "indexed 6 run(s)"
    h = station("history", "GYRO-001", env={"STATION_HISTORY_URL": postgres})
    assert h.returncode == 0 and h.stdout.count("completed") == 6
    _check_shift_flagged(days, postgres, tmp_path / "trend.png")
    # the same numbers as SQLite's: the flagged line is identical
    a = station("trend", "ISU-000-001", "--db", postgres, "--plot", str(tmp_path / "a.png"))
    b = station("trend", "ISU-000-001", "--db", str(days["db"]), "--plot",
                str(tmp_path / "b.png"))
    assert [x for x in a.stdout.splitlines() if x.startswith("flagged")] == \
        [x for x in b.stdout.splitlines() if x.startswith("flagged")]
