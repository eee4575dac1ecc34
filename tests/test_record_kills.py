"""SIGKILL at random moments, then --resume: the record equals the uninterrupted run's.

Each kill is a real `python -m laboratory.cli ... --quiet` process killed with SIGKILL as soon
as its journal holds a number of records drawn (stratified, seeded) over the run, so what
the campaign covers does not depend on the machine's speed: turn-on, survey, the position
charts, the computations, the alignments and the final writes of sheets, plots and
results (a kill at "all but the end note"). Some kills hit a resume itself, during its
replay or after it. Every resume must append to the journal (never rewrite it), set a torn
last line aside, journal no step twice, and end with `station compare` finding no
difference against the uninterrupted run. 20 kills of the day, 5 of the gyrocompassing
test (each killed journal also analysed with --analyse: the completed runs, exactly), 5
of the ESG calibration.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from rich.console import Console
from typer.testing import CliRunner

from laboratory.cigtf.gyrocompassing import analyse_journal, run_gyrocompass_test
from laboratory.cli import app
from laboratory.compare import differences
from laboratory.esg.calibration import run_esg_calibration
from laboratory.isu.day import DayRequest, run_day
from station.config.isu import load_config

REPO = Path(__file__).resolve().parents[1]
QUIET = Console(quiet=True)
HANG_GUARD_S = 600.0  # a hang guard for one killed process, not a speed figure
DAY_SEED, FULL_SEED, GC_SEED, ESG_SEED = 21, 22, 23, 24
SHORT = ("--only", "II-11", "--only", "II-13", "--positions", "7")


def lines(path: Path) -> int:
    return path.read_bytes().count(b"\n") if path.exists() else 0


def kill_at(args: list[str], journal: Path, at: int | tuple[str, int]) -> bytes:
    """Run `station <args>` and SIGKILL it once ``journal`` holds ``at`` lines (or, for
    ``("sheets", m)``, once the run has written ``m`` sheet files: inside the final
    writes); the journal's bytes at the kill."""
    sheets = journal.parent / "sheets"

    def due(n: int) -> bool:
        if isinstance(at, int):
            return n >= at
        return sheets.is_dir() and len(os.listdir(sheets)) >= at[1]

    err = journal.parent.parent / f"{journal.parent.name}.stderr"
    with open(err, "wb") as stderr:
        proc = subprocess.Popen([sys.executable, "-m", "laboratory.cli", *args], cwd=REPO,
                                stdout=subprocess.DEVNULL, stderr=stderr)
    pos, n = 0, 0
    end = time.monotonic() + HANG_GUARD_S
    try:
        while not due(n):
            if proc.poll() is not None:
                pytest.fail(f"station {' '.join(args)} ended (exit {proc.returncode}) "
                            f"before {at} records: {err.read_text()[-2000:]}")
            if time.monotonic() > end:
                pytest.fail(f"station {' '.join(args)}: no {at} records (hang guard)")
            try:
                with open(journal, "rb") as f:
                    f.seek(pos)
                    data = f.read()
            except FileNotFoundError:
                data = b""
            pos += len(data)
            n += data.count(b"\n")
            if not due(n):
                time.sleep(0.0005)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(60)
    assert proc.returncode == -signal.SIGKILL
    data = journal.read_bytes()
    whole = data[:data.rfind(b"\n") + 1]
    last = json.loads(whole.splitlines()[-1]) if whole else {}
    count = len(whole.splitlines())
    print(f"killed {journal.parent.name} at {count} records ({phase(last, journal.parent)})")
    return data


def phase(rec: dict, d: Path) -> str:
    """Where a kill landed, from the journal's last whole record."""
    if rec.get("event") == "resume":
        return "resume replay"
    if (d / "sheets").is_dir() and rec.get("event") != "end":
        return f"final writes, {len(os.listdir(d / 'sheets'))} sheet files"
    chart = str(rec.get("chart") or rec.get("key") or rec.get("name") or rec.get("event"))
    return chart


def resume(args: list[str], d: Path, ref: Path, killed: list[bytes]) -> None:
    """Resume in ``d`` (in-process) and check the record and the journal's history."""
    r = CliRunner().invoke(app, [*args, "--resume", str(d)])
    assert r.exit_code == 0, r.output[-3000:]
    journal = (d / "journal.jsonl").read_bytes()
    for before in killed:  # every earlier state's whole records are still the journal's start
        assert journal.startswith(before[:before.rfind(b"\n") + 1])
    torn = [b[b.rfind(b"\n") + 1:] for b in killed]
    side = sorted(d.glob("journal.jsonl.torn-*"), key=lambda p: int(p.name.rsplit("-", 1)[1]))
    assert [p.read_bytes() for p in side] == [t for t in torn if t]
    recs = [json.loads(x) for x in journal.splitlines()]
    steps = [(x["chart"], x["step"]) for x in recs if x["kind"] == "step"]
    assert len(steps) == len(set(steps))  # replayed, never journaled twice
    assert [x.get("event") for x in recs].count("end") == 1 and recs[-1]["event"] == "end"
    assert differences(ref, d) == []


def stratified(rng: random.Random, lo: int, hi: int, k: int) -> list[int]:
    """``k`` draws from [lo, hi), one in each of k equal strata."""
    edges = [lo + (hi - lo) * i // k for i in range(k + 1)]
    return [rng.randrange(a, max(a + 1, b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]


@pytest.fixture(scope="module")
def short_day(tmp_path_factory):
    ref = tmp_path_factory.mktemp("short") / "ref"
    run_day(DayRequest(load_config(seed=DAY_SEED), ref, only=("II-11", "II-13"),
                       positions=(7,), quiet=True), QUIET)
    return ref, lines(ref / "journal.jsonl")


def test_day_killed_at_random_records_resumes_identical(short_day, tmp_path):
    """10 kills of a short day (turn-on, survey, positions 7 and 8 of II-11 and II-13,
    the computations, the mirror alignment), the last inside the writing of its sheets."""
    ref, n = short_day
    rng = random.Random(1201)
    n_sheets = len(os.listdir(ref / "sheets"))
    points: list = [*stratified(rng, 1, n - 1, 9), ("sheets", rng.randrange(1, n_sheets))]
    for i, at in enumerate(points):
        d = tmp_path / f"k{i}"
        args = ["day", "--quiet", "--seed", str(DAY_SEED), *SHORT]
        killed = kill_at([*args, "--out", str(d)], d / "journal.jsonl", at)
        resume(["day", "--quiet"], d, ref, [killed])


def test_day_killed_inside_its_resume_resumes_identical(short_day, tmp_path):
    """3 days killed, then their resume killed too: during the replay (right after the
    resume's note) or after it; the third resume finishes the record."""
    ref, n = short_day
    rng = random.Random(1202)
    for i, (first, extra) in enumerate([(rng.randrange(2, n // 3), 0),
                                        (rng.randrange(n // 3, 2 * n // 3), 0),
                                        (rng.randrange(2, n // 2), None)]):
        d = tmp_path / f"r{i}"
        args = ["day", "--quiet", "--seed", str(DAY_SEED), *SHORT]
        killed = [kill_at([*args, "--out", str(d)], d / "journal.jsonl", first)]
        whole = killed[0].count(b"\n")
        extra = rng.randrange(1, n - whole - 1) if extra is None else extra
        killed.append(kill_at(["day", "--quiet", "--resume", str(d)], d / "journal.jsonl",
                              whole + 1 + extra))
        resume(["day", "--quiet"], d, ref, killed)


def test_full_day_killed_in_each_part_resumes_identical(tmp_path):
    """4 kills of the full day: in the measurement charts, in the computations and the
    parameter evaluation, in the level and gyrocompass alignments, in the final writes."""
    ref = tmp_path / "ref"
    run_day(DayRequest(load_config(seed=FULL_SEED), ref, quiet=True), QUIET)
    recs = [json.loads(x) for x in (ref / "journal.jsonl").read_text().splitlines()]
    first = {c: next(i for i, r in enumerate(recs) if r.get("chart") == c)
             for c in ("II-6", "II-15", "III-4")}
    rng = random.Random(1203)
    points = [rng.randrange(first["II-6"], first["II-15"]),
              rng.randrange(first["II-15"], first["III-4"]),
              rng.randrange(first["III-4"], len(recs) - 1),
              ("sheets", rng.randrange(1, len(os.listdir(ref / "sheets"))))]
    for i, at in enumerate(points):
        d = tmp_path / f"f{i}"
        killed = kill_at(["day", "--quiet", "--seed", str(FULL_SEED), "--out", str(d)],
                         d / "journal.jsonl", at)
        resume(["day", "--quiet"], d, ref, [killed])


def test_gyrocompass_test_killed_is_analysed_and_resumes_identical(tmp_path):
    """5 kills of the 52-hour CIGTF test; --analyse recovers every completed run of each
    killed journal exactly (and leaves the journal as it was), --resume the whole test."""
    ref = tmp_path / "ref"
    full = run_gyrocompass_test(GC_SEED, ref)
    n = lines(ref / "journal.jsonl")
    rng = random.Random(1204)
    last = ("sheets", rng.randrange(1, len(os.listdir(ref / "sheets"))))
    for i, at in enumerate([*stratified(rng, 1, n - 1, 4), last]):
        d = tmp_path / f"g{i}"
        killed = kill_at(["gyrocompass-test", "--seed", str(GC_SEED), "--out", str(d)],
                         d / "journal.jsonl", at)
        got = analyse_journal(d)
        assert (d / "journal.jsonl").read_bytes() == killed
        for ph in ("operating", "shutdown"):
            mine = [r for r in got["runs"] if r["phase"] == ph]
            assert mine == [r for r in full["runs"] if r["phase"] == ph][:len(mine)]
        if len(got["runs"]) == len(full["runs"]):
            assert got["phases"] == full["phases"] and got["tests"] == full["tests"]
        resume(["gyrocompass-test"], d, ref, [killed])


def test_esg_calibration_killed_resumes_identical(tmp_path):
    """5 kills of the ESG calibration (acquisition steps 1-13, reduction, study, writes)."""
    ref = tmp_path / "ref"
    run_esg_calibration(ESG_SEED, ref)
    n = lines(ref / "journal.jsonl")
    rng = random.Random(1205)
    for i, at in enumerate(stratified(rng, 1, n - 1, 4) + [n - 1]):
        d = tmp_path / f"e{i}"
        killed = kill_at(["esg-calibration", "--seed", str(ESG_SEED), "--out", str(d)],
                         d / "journal.jsonl", at)
        resume(["esg-calibration"], d, ref, [killed])
