"""Rehearsals: `station day --links` against `station serve` in another process, at 500x.

The survey and calibration positions 7 and 8 run through the command line over ptys and
socketcand while a second, plain python-can client decodes the IEU's frames with the DBC.
The sheets must equal those of the virtual twin (same seed, begun at the same simulated
instant) within the tolerances of station.hil.twin (docs/hil.md says why these). Stopping
the server mid-run must stop the client naming the link, keep the completed steps, and
a restarted server plus --resume must finish the run. No assertion depends on wall time.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hil_helpers import start, stop, text

from laboratory.isu.day import DayRequest, run_day
from station.config.isu import StationConfig, load_config
from station.hil.twin import Tolerances, compare_rehearsal

SPEED = 500.0
SEED = 11
DAY = ["--only", "II-11", "--only", "II-13", "--positions", "7", "--positions", "8"]
RUN_DEADLINE_S = 240.0
# the record, not the machine: how late the rehearsal ran depends on the load (an earlier
# run than the twin is still refused)
RECORD = Tolerances(check_late=False)


def _serve(base: Path, extra: tuple[str, ...] = ()) -> tuple[Path, subprocess.Popen]:
    base.mkdir(parents=True, exist_ok=True)
    return start(base, ["--seed", str(SEED), "--speed", str(SPEED), *extra])


def _station(*args: str, timeout: float = RUN_DEADLINE_S) -> subprocess.CompletedProcess:
    env = {**os.environ, "COLUMNS": "200"}
    return subprocess.run([sys.executable, "-m", "laboratory.cli", *args], capture_output=True,
                          text=True, timeout=timeout, env=env, stdin=subprocess.DEVNULL)


def _journal(run: Path) -> list[dict]:
    """Complete records of a run's journal (none yet if it does not exist)."""
    path = run / "journal.jsonl"
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:  # a record being written
            break
    return out


@pytest.fixture(scope="module")
def rehearsal(tmp_path_factory):
    """One served rack; the day's survey and positions 7, 8 over its links, sniffed."""
    base = tmp_path_factory.mktemp("rehearsal")
    links, server = _serve(base)
    sniffer = subprocess.Popen(
        [sys.executable, "-m", "station.hil.sniff", "--links", str(links),
         "--out", str(base / "sniff.jsonl")],
        stdout=subprocess.DEVNULL, stderr=open(base / "sniff.err", "w"))
    try:
        check = _station("check", "--links", str(links), "--json", timeout=60)
        day = _station("day", "--links", str(links), "--seed", str(SEED), *DAY,
                       "--out", str(base / "run"), "--quiet")
        cal = base / "calibration"
        run_day(DayRequest(load_config(seed=SEED), cal, quiet=True, align=False))  # for III-4
        align = _station("align", "--method", "level", "--calibration", str(cal),
                         "--links", str(links), "--seed", str(SEED),
                         "--out", str(base / "align"), "--quiet")
    finally:
        stop(sniffer)
        code = stop(server)
    assert code == 0, text(base / "server.err")
    yield {"base": base, "day": day, "align": align, "check": check}


def test_day_over_links_equals_its_virtual_twin(rehearsal, tmp_path):
    base, day = rehearsal["base"], rehearsal["day"]
    assert day.returncode == 0, day.stdout[-3000:] + day.stderr[-3000:]
    run = base / "run"
    start = next(r for r in _journal(run) if r.get("event") == "start")
    assert start["links"] and start["session"]
    twin = tmp_path / "twin"
    run_day(DayRequest(load_config(seed=SEED), twin, quiet=True, only=("II-11", "II-13"),
                       positions=(7, 8), start_s=start["t_sim"]))
    assert compare_rehearsal(run, twin, RECORD) == []
    cmp = _station("compare", "--rehearsal", str(run), str(twin), timeout=60)
    late = [p for p in compare_rehearsal(run, twin) if "from the twin" in p]
    if late:  # the command line says why, naming the late steps
        assert cmp.returncode == 1 and "from the twin" in cmp.stdout
    else:
        assert cmp.returncode == 0 and "equal within the real-time tolerances" in cmp.stdout
    sheets = {p.stem for p in (run / "sheets").glob("*.json")}
    assert {"check_I-1", "check_I-2", "check_II-11", "check_II-13", "survey_results",
            "counter_outputs"} <= sheets
    outputs = json.loads((run / "sheets" / "counter_outputs.json").read_text())["outputs"]
    assert sorted(outputs) == ["accel 7", "accel 8", "gyro 7", "gyro 8"]
    # the served world is the client's (same seed and config): truth is known
    res = json.loads((run / "results.json").read_text())
    assert res["links"] and all(r["truth"] is not None for r in res["calibration"])


def test_twin_comparison_can_fail(rehearsal, tmp_path):
    """A twin begun at another instant, or of another seed, is told apart."""
    run = rehearsal["base"] / "run"
    early = tmp_path / "early"
    run_day(DayRequest(load_config(seed=SEED), early, quiet=True, only=("II-11", "II-13"),
                       positions=(7, 8), start_s=0.0))
    assert any("from the twin" in p for p in compare_rehearsal(run, early))
    start = next(r for r in _journal(run) if r.get("event") == "start")["t_sim"]
    data = load_config(seed=SEED).model_dump()
    data["isu"]["gyros"][0]["R_deg_hr"] += 0.2  # 40 pulses in a 600 s gate
    other = tmp_path / "other"
    run_day(DayRequest(StationConfig.model_validate(data), other, quiet=True,
                       only=("II-11", "II-13"), positions=(7, 8), start_s=start))
    problems = compare_rehearsal(run, other, RECORD)
    assert problems and all("counter_outputs gyro" in p for p in problems), problems


def test_check_over_links_reaches_every_served_instrument(rehearsal):
    check = rehearsal["check"]
    assert check.returncode == 0, check.stdout + check.stderr
    rows = json.loads(check.stdout)
    links = rehearsal["base"] / "links"
    assert len(rows) == 13 and all(r["ok"] for r in rows)
    assert all(r["link"].startswith(str(links)) for r in rows if r["instrument"] != "ieu")
    assert next(r for r in rows if r["instrument"] == "ieu")["link"].startswith("socketcand:")


def test_second_client_decodes_ieu_frames_with_the_dbc(rehearsal):
    frames = [json.loads(line) for line in
              (rehearsal["base"] / "sniff.jsonl").read_text().splitlines()]
    assert frames, (rehearsal["base"] / "sniff.err").read_text()
    assert not [f for f in frames if "error" in f]
    names = {f["name"] for f in frames}
    # turn-on's status exchanges (I-1 step 8) and the level alignment's samples (III-4)
    assert {"IEU_COMMAND", "IEU_STATUS", "IEU_GYRO", "IEU_ACCEL_A", "IEU_ACCEL_B",
            "IEU_TIMER"} <= names
    starts = [f["signals"] for f in frames
              if f["name"] == "IEU_COMMAND" and f["signals"]["Command"] == 1]
    assert starts, "no START command seen"
    period = starts[-1]["PeriodTicks"]
    after = frames[max(i for i, f in enumerate(frames) if f["name"] == "IEU_COMMAND"
                       and f["signals"]["Command"] == 1):]
    timers = [f["signals"] for f in after if f["name"] == "IEU_TIMER"]
    # the alignment's samples: each timer frame counts one whole commanded period, and
    # the sequence numbers run on without a gap (nothing lost on the way to the sniffer)
    assert len(timers) >= 10
    assert {t["Timer"] for t in timers} == {period}
    seqs = [t["Seq"] for t in timers]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))


def test_level_alignment_over_links(rehearsal):
    align = rehearsal["align"]
    assert align.returncode == 0, align.stdout[-3000:] + align.stderr[-3000:]
    res = json.loads((rehearsal["base"] / "align" / "results.json").read_text())
    (entry,) = res["alignment"]
    assert entry["method"] == "level"
    # the table's attitude is the server's: no error against truth over links
    assert entry["level_error_arcsec"] == [None, None]
    t = entry["T"]
    # an orthonormal attitude matrix, level axis within the survey's few arcmin of vertical
    assert abs(sum(x * x for x in t[2]) - 1.0) < 1e-9


def test_server_stop_fails_naming_the_link_then_resume_finishes(tmp_path):
    run = tmp_path / "run"
    links, server = _serve(tmp_path / "server1")
    client = subprocess.Popen(
        [sys.executable, "-m", "laboratory.cli", "day", "--links", str(links), "--seed",
         str(SEED), *DAY, "--out", str(run), "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        env={**os.environ, "COLUMNS": "300"})
    try:
        deadline = time.monotonic() + RUN_DEADLINE_S
        while not any(r.get("chart") == "II-11" and r.get("kind") == "step"
                      for r in _journal(run)):
            assert client.poll() is None, client.stdout.read()
            if time.monotonic() > deadline:  # a hang guard, not a speed figure
                pytest.fail("the client never reached Chart II-11")
            time.sleep(0.05)
        stop(server)  # mid-chart II-11
        out, _ = client.communicate(timeout=60)
    finally:
        if client.poll() is None:
            client.kill()
        stop(server)
    assert client.returncode == 1, out
    assert "stopped:" in out and str(links) in out.replace("\n", ""), out
    before = _journal(run)
    done = {(r["chart"], r["step"]) for r in before if r["kind"] == "step"}
    assert ("I-2", "9") in done and ("II-11", "1") in done
    survey_before = next(r["data"] for r in before
                         if r["kind"] == "sheet" and r["name"] == "survey_results")

    links, server = _serve(tmp_path / "server2")  # a new session: the rack was power-cycled
    try:
        res = _station("day", "--links", str(links), "--seed", str(SEED), *DAY,
                       "--resume", str(run), "--quiet")
    finally:
        stop(server)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    after = _journal(run)
    assert after[:len(before)] == before  # appended, never rewritten
    restored = [r["block"] for r in after if r.get("event") == "restored"]
    assert restored == ["I-2"]  # turn-on repeated (new session), survey restored
    survey = json.loads((run / "sheets" / "survey_results.json").read_text())
    assert survey["t_bi"] == survey_before["t_bi"]
    outputs = json.loads((run / "sheets" / "counter_outputs.json").read_text())["outputs"]
    assert sorted(outputs) == ["accel 7", "accel 8", "gyro 7", "gyro 8"]
    ii11 = json.loads((run / "sheets" / "check_II-11.json").read_text())
    assert [s["number"] for s in ii11["steps"]][:4] == ["1", "2", "3", "4"]
    assert all(s["done"] for s in ii11["steps"])


def test_fault_configured_on_the_server_is_reported_by_the_procedure(tmp_path):
    """A table axis that seizes in the served rack: the day stops at the step that needs it,
    naming the chart, the step and the axis, as the table driver sees it."""
    faults = tmp_path / "faults.toml"
    faults.write_text("[faults.table]\nstall_axis = 3\nstall_after_s = 0.0\n")
    links, server = _serve(tmp_path / "server", ("--config", str(faults)))
    try:
        res = _station("day", "--links", str(links), "--seed", str(SEED), *DAY,
                       "--out", str(tmp_path / "run"), "--quiet")
    finally:
        stop(server)
    said = " ".join(res.stderr.split())  # stop messages go to stderr
    assert res.returncode == 1, said
    assert "stopped: Chart I-2, step 2" in said and "axis 3 (MOVING) not settled" in said
    steps = [(r["chart"], r["step"]) for r in _journal(tmp_path / "run") if r["kind"] == "step"]
    assert ("I-1", "11") in steps and ("I-2", "1") in steps  # turn-on done, then stopped
