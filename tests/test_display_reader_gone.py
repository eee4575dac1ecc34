"""A run whose stdout loses its reader (`station day | head -1`) goes on to the end of its
record (laboratory.console): the same record as a run read to the end, its exit, and one
line on stderr. rich's own answer (end the process, exit 1) left the day aborted at
Chart I-1, and the gyrocompassing test and the ESG calibration aborted without their plots
or end note while their tables printed."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
from pathlib import Path

import pytest

from laboratory.compare import differences
from laboratory.console import NOTE

COMMANDS = {"day": ("results.json", "report.html", "results.png", "nonlinearity.png"),
            "gyrocompass-test": ("gyrocompass.json", "report.html", "gyrocompass.png"),
            "esg-calibration": ("esg.json", "report.html")}


def _run(command: str, out: Path, seed: int, *, closed: str,
         extra: tuple[str, ...] = ()) -> subprocess.CompletedProcess[bytes]:
    """`station COMMAND` with stdout ("stdout") or stdout and stderr ("both") into a pipe
    whose reader is gone before the run writes a byte; "none": read to the end."""
    args = [sys.executable, "-m", "laboratory.script", command, "--seed", str(seed),
            "--out", str(out), *extra]
    if closed == "none":
        return subprocess.run(args, capture_output=True, check=False)
    r, w = os.pipe()
    try:
        p = subprocess.Popen(args, stdout=w, stderr=w if closed == "both" else subprocess.PIPE)
    finally:
        os.close(w)
        os.close(r)  # the reader is gone: the run's first line meets a broken pipe
    _, err = p.communicate()
    return subprocess.CompletedProcess(args, p.returncode, b"", err or b"")


@pytest.fixture(scope="module")
def seed() -> int:
    return random.Random(20261128).randrange(0, 2**31)


def _reference(tmp: Path, command: str, seed: int) -> tuple[Path, int]:
    """The run read to the end: its record and its exit (0, or 3 on a FAIL verdict)."""
    done = _run(command, tmp / "read", seed, closed="none")
    assert done.returncode in (0, 3), done.stderr.decode()
    assert NOTE not in done.stderr.decode()
    return tmp / "read", done.returncode


def _same_record(command: str, out: Path, done: subprocess.CompletedProcess[bytes],
                 ref: tuple[Path, int]) -> None:
    read, code = ref
    assert done.returncode == code, done.stderr.decode()
    run = json.loads((out / "run.json").read_text())
    assert (run["status"], run["exit_code"]) == ("completed", code)
    for name in COMMANDS[command]:
        assert (out / name).is_file(), name
    assert sorted(p.name for p in out.glob("*.png")) == sorted(p.name for p in read.glob("*.png"))
    assert (out / "journal.jsonl").read_text().count('"event":"end"') == 1
    assert differences(read, out) == []  # every sheet value and result, run.json's too


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_run_without_its_reader_keeps_its_whole_record(tmp_path: Path, seed: int,
                                                          command: str) -> None:
    ref = _reference(tmp_path, command, seed)
    done = _run(command, tmp_path / "gone", seed, closed="stdout")
    _same_record(command, tmp_path / "gone", done, ref)
    assert done.stderr.decode().count(NOTE) == 1


def test_stderr_in_the_same_closed_pipe_loses_nothing_either(tmp_path: Path, seed: int) -> None:
    ref = _reference(tmp_path, "day", seed)
    done = _run("day", tmp_path / "both", seed, closed="both")
    _same_record("day", tmp_path / "both", done, ref)


def test_a_quiet_day_whose_last_line_has_no_reader_ends_as_its_record_says(
        tmp_path: Path, seed: int) -> None:
    """--quiet: the record's path is the first line written, after the record is complete;
    its broken pipe is the console's too (click's own answer was exit 1, the record's 0)."""
    ref = _reference(tmp_path, "day", seed)
    done = _run("day", tmp_path / "quiet", seed, closed="stdout", extra=("--quiet",))
    _same_record("day", tmp_path / "quiet", done, ref)
    assert done.stderr.decode().count(NOTE) == 1
