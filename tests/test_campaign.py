"""station campaign: reproducible tasks, the same Parquet rows in process, on a LocalCluster
and on a real `dask scheduler` with two `dask worker` processes, no task lost with a killed
worker, and a resume that runs only what an interrupted client had not stored.

The tasks are CIGTF gyrocompassing tests (the cheapest laboratory run, about 2 s each).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from laboratory.campaign.run import run_campaign
from laboratory.campaign.spec import CampaignSpec, SpecError, load_spec, tasks
from laboratory.campaign.store import CampaignStore
from laboratory.campaign.summary import interval

ROOT = Path(__file__).resolve().parents[1]
SPEC = """command = "gyrocompass-test"
seeds = 4
seed = 18
[grid]
latitude_deg = [32.89, 45.0]
"""
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def spec() -> CampaignSpec:
    return CampaignSpec.model_validate({"command": "gyrocompass-test", "seeds": 4, "seed": 18,
                                        "grid": {"latitude_deg": [32.89, 45.0]}})


def rows(out: Path) -> pd.DataFrame:
    return CampaignStore(out).table("rows")


def wait_for(cond: Any, what: str, timeout: float = 120.0) -> None:
    """Poll ``cond`` until true (a generous timeout, not a timing assertion)."""
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.1)


@pytest.fixture(scope="module")
def serial(tmp_path_factory: pytest.TempPathFactory) -> pd.DataFrame:
    """The 8 tasks run one after another in this process: the reference rows."""
    out = tmp_path_factory.mktemp("serial") / "c"
    res = run_campaign(spec(), out, workers=0)
    assert (res.n_tasks, res.ran, res.failed) == (8, 8, 0)
    return rows(out)


# -- the spec and its tasks ------------------------------------------------------------------

def test_tasks_are_seeded_from_the_campaign_seed_and_index() -> None:
    a = tasks(spec())
    assert [t.index for t in a] == list(range(8))
    assert [t.values["latitude_deg"] for t in a] == [32.89] * 4 + [45.0] * 4
    assert len({t.seed for t in a}) == 8
    assert tasks(spec()) == a  # reproducible
    more = tasks(spec().model_copy(update={"seeds": 6}))
    assert [t.seed for t in more[:4]] == [t.seed for t in a[:4]]  # index's, not n's
    other = tasks(spec().model_copy(update={"seed": 19}))
    assert not {t.seed for t in other} & {t.seed for t in a}


def test_random_draws_are_the_tasks_own() -> None:
    s = CampaignSpec.model_validate({"command": "esg-calibration", "seeds": 5, "seed": 3,
                                     "random": {"drift_deg_hr": [0.0, 0.1]}})
    draws = [t.values["drift_deg_hr"] for t in tasks(s)]
    assert all(0.0 <= d <= 0.1 for d in draws) and len(set(draws)) == 5
    assert draws == [t.values["drift_deg_hr"] for t in tasks(s)]
    bigger = s.model_copy(update={"seeds": 7})
    assert [t.values["drift_deg_hr"] for t in tasks(bigger)][:5] == draws


def test_a_bad_spec_is_refused_naming_the_field(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text('command = "dance"\n')
    with pytest.raises(SpecError, match=r"s\.toml: command: .*unknown command 'dance'"):
        load_spec(f)
    f.write_text('command = "day"\n[random]\n"site.latitude_deg" = [50.0, 40.0]\n')
    with pytest.raises(SpecError, match=r"random: .*site\.latitude_deg.*not a range"):
        load_spec(f)


def test_a_bad_override_is_the_tasks_failure(tmp_path: Path) -> None:
    s = CampaignSpec.model_validate({"command": "gyrocompass-test", "seeds": 1,
                                     "grid": {"no_such_field": [1.0]}})
    res = run_campaign(s, tmp_path / "c", workers=0)
    assert (res.ran, res.failed) == (1, 1)
    f = CampaignStore(tmp_path / "c").table("failures")
    assert f["message"].tolist() == ["ValueError: config override 'no_such_field': no field "
                                     "'no_such_field' in CigtfParams"]
    summary = json.loads((tmp_path / "c" / "summary.json").read_text())
    assert summary["failures"][0]["message"] == f["message"][0]


def test_chi_square_interval() -> None:
    lo, hi = interval(100)  # the tables' chi^2(100): 67.328 and 140.169 at 0.5 % and 99.5 %
    assert lo == pytest.approx((67.328 / 100) ** 0.5, abs=1e-5)
    assert hi == pytest.approx((140.169 / 100) ** 0.5, abs=1e-5)


# -- the same rows wherever the tasks run ----------------------------------------------------

def test_serial_rows_are_the_simulators_truth(serial: pd.DataFrame) -> None:
    theta = serial[serial["parameter"] == "theta"]
    assert len(theta) == 16 and theta["task"].nunique() == 8
    assert (theta["z"].abs() < 5).all()  # each phase's theta within 5 sigma of the truth
    assert ((theta["estimate"] - theta["truth"]) == theta["error"]).all()


def test_local_cluster_of_two_workers_gives_the_serial_rows(
        tmp_path: Path, serial: pd.DataFrame) -> None:
    res = run_campaign(spec(), tmp_path / "c", workers=2)
    assert (res.ran, res.failed) == (8, 0)
    pd.testing.assert_frame_equal(rows(tmp_path / "c"), serial)
    workers = set(CampaignStore(tmp_path / "c").table("tasks")["worker"])
    assert len(workers) == 2 and os.getpid() not in {int(w.rsplit(":")[1]) for w in workers}


def _start(args: list[str], log: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-m", "dask", *args], env=ENV, cwd=ROOT,
                            stdout=log.open("wb"), stderr=subprocess.STDOUT)


def _stop(p: subprocess.Popen[bytes]) -> None:
    if p.poll() is None:
        p.terminate()
        try:
            p.wait(30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def _scheduler_address(sched_file: Path) -> str:
    """The scheduler's address once its file is whole; '' while it is absent or still being
    written (the scheduler creates the file before it writes the JSON: CI once read it empty)."""
    try:
        return str(json.loads(sched_file.read_text())["address"])
    except (OSError, ValueError, KeyError):
        return ""


@pytest.fixture
def dask_cluster(tmp_path: Path) -> Iterator[tuple[str, dict[str, subprocess.Popen[bytes]]]]:
    """A `dask scheduler` and two `dask worker` processes (no nanny) on 127.0.0.1, free
    ports; yields the scheduler's address and the workers by name; stops them all."""
    from distributed import Client

    sched_file = tmp_path / "scheduler.json"
    procs = [_start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                     "--scheduler-file", str(sched_file)], tmp_path / "scheduler.log")]
    workers: dict[str, subprocess.Popen[bytes]] = {}
    try:
        wait_for(lambda: _scheduler_address(sched_file), "the scheduler file")
        address = _scheduler_address(sched_file)
        for name in ("w1", "w2"):
            workers[name] = _start(["worker", "--scheduler-file", str(sched_file), "--host",
                                    "127.0.0.1", "--nthreads", "1", "--no-nanny",
                                    "--no-dashboard", "--name", name],
                                   tmp_path / f"{name}.log")
            procs.append(workers[name])
        with Client(address, timeout="60s") as c:
            c.wait_for_workers(2, timeout=120)
        yield address, workers
    finally:
        for p in reversed(procs):
            _stop(p)


def test_a_real_scheduler_and_two_workers_give_the_serial_rows(
        tmp_path: Path, serial: pd.DataFrame,
        dask_cluster: tuple[str, dict[str, subprocess.Popen[bytes]]]) -> None:
    address, workers = dask_cluster
    res = run_campaign(spec(), tmp_path / "c", scheduler=address)
    assert (res.ran, res.failed) == (8, 0)
    pd.testing.assert_frame_equal(rows(tmp_path / "c"), serial)
    pids = {int(w.rsplit(":")[1]) for w in CampaignStore(tmp_path / "c").table("tasks")["worker"]}
    assert pids == {p.pid for p in workers.values()}


def test_killing_a_worker_mid_campaign_loses_no_task(
        tmp_path: Path, serial: pd.DataFrame,
        dask_cluster: tuple[str, dict[str, subprocess.Popen[bytes]]]) -> None:
    from distributed import Client

    address, workers = dask_cluster
    killed: list[tuple[str, list[str]]] = []

    def kill_one_busy_worker(_: dict[str, Any]) -> None:
        if killed:
            return
        with Client(address, timeout="30s") as c:
            names = {a: w["name"] for a, w in c.scheduler_info()["workers"].items()}
            busy = [(names[a], keys) for a, keys in c.processing().items() if keys]
        if busy:  # a worker with a task under way: it dies with it
            name, keys = busy[0]
            workers[name].send_signal(signal.SIGKILL)
            workers[name].wait(30)
            killed.append((name, [str(k) for k in keys]))

    res = run_campaign(spec(), tmp_path / "c", scheduler=address,
                       on_stored=kill_one_busy_worker)
    assert killed, "no worker was busy when the first task was stored"
    assert (res.ran, res.failed) == (8, 0)
    pd.testing.assert_frame_equal(rows(tmp_path / "c"), serial)  # all 8, same values
    name, lost = killed[0]
    dead_pid = workers[name].pid
    done = CampaignStore(tmp_path / "c").table("tasks")
    for key in lost:  # the task under way on the dead worker ran again elsewhere
        row = done[done["task"] == int(key.rsplit("-", 1)[1])]
        assert int(row["worker"].iloc[0].rsplit(":")[1]) != dead_pid


# -- the command line and resuming -----------------------------------------------------------

def test_resume_after_an_interrupted_client_runs_only_the_missing_tasks(
        tmp_path: Path, serial: pd.DataFrame) -> None:
    f = tmp_path / "spec.toml"
    f.write_text(SPEC)
    out = tmp_path / "c"
    p = subprocess.Popen([sys.executable, "-m", "laboratory.cli", "campaign", str(f),
                          "--out", str(out), "--workers", "0", "--quiet"], env=ENV, cwd=ROOT,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_for(lambda: len(CampaignStore(out).done()) >= 3 or p.poll() is not None,
                 "three stored tasks")
    finally:
        p.send_signal(signal.SIGKILL)
        p.wait()
    stored = CampaignStore(out).done()
    assert 3 <= len(stored) < 8, "the client finished before it was interrupted"
    stamps = {i: (out / "tasks" / f"part-{i:06d}.parquet").stat().st_mtime_ns for i in stored}
    again = subprocess.run([sys.executable, "-m", "laboratory.cli", "campaign", str(f),
                            "--out", str(out)], env=ENV, cwd=ROOT, capture_output=True,
                           text=True)
    assert again.returncode == 2
    assert again.stderr.strip() == (f"error: --out {out}: already holds a campaign "
                                    "(--resume to continue it)")
    res = run_campaign(load_spec(f), out, workers=0, resume=True)
    assert (res.ran, res.stored_before) == (8 - len(stored), len(stored))
    assert {i: (out / "tasks" / f"part-{i:06d}.parquet").stat().st_mtime_ns
            for i in stored} == stamps  # the stored tasks were not run again
    pd.testing.assert_frame_equal(rows(out), serial)
    summary = pd.read_csv(out / "summary.csv")
    theta = summary[summary["parameter"] == "theta"]
    assert theta["n"].tolist() == [4, 4, 4, 4]


def test_resume_of_another_spec_is_refused(tmp_path: Path) -> None:
    s = CampaignSpec.model_validate({"command": "gyrocompass-test", "seeds": 1,
                                     "grid": {"no_such_field": [1.0]}})
    run_campaign(s, tmp_path / "c", workers=0)
    with pytest.raises(SpecError, match="started from another spec"):
        run_campaign(s.model_copy(update={"seed": 5}), tmp_path / "c", workers=0, resume=True)


def test_a_day_plan_path_on_another_laboratory_is_the_tasks_failure(tmp_path: Path) -> None:
    s = CampaignSpec.model_validate({"command": "esg-calibration", "seeds": 1,
                                     "grid": {"plan.min_turns": [20]}})
    res = run_campaign(s, tmp_path / "c", workers=0)
    assert (res.ran, res.failed) == (1, 1)
    assert CampaignStore(tmp_path / "c").table("failures")["message"].tolist() == [
        "ValueError: plan.min_turns: the day plan is the isu laboratory's, not esg's"]
