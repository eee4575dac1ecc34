"""A command's display made while the plot is drawn (laboratory.shown, issue 17): shown
once, and an error of it never cuts the record short."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from laboratory.cigtf.gyrocompassing import run_gyrocompass_test
from laboratory.shown import Shown


def test_shown_once_early_or_at_done() -> None:
    seen: list[dict] = []
    early = Shown(seen.append)
    early.meanwhile({"a": 1})
    early.done({"a": 2})
    assert seen == [{"a": 1}]
    late = Shown(seen.append)
    late.done({"b": 1})  # a run that drew no plot: shown where it used to be
    assert seen == [{"a": 1}, {"b": 1}]
    Shown(None).meanwhile({})  # nothing to show: only the report's template
    Shown(None).done({})


def test_a_display_error_is_raised_after_the_record_is_complete(tmp_path: Path) -> None:
    def show(res: dict) -> None:
        raise BrokenPipeError(32, "Broken pipe")

    shown = Shown(show)
    res = run_gyrocompass_test(3, tmp_path, show=shown)  # the run ends normally
    journal = [json.loads(line) for line in
               (tmp_path / "journal.jsonl").read_text().splitlines()]
    assert journal[-1].get("event") == "end"
    assert (tmp_path / "gyrocompass.png").is_file()
    assert json.loads((tmp_path / "gyrocompass.json").read_text())["seed"] == 3
    assert (tmp_path / "report.html").is_file()
    with pytest.raises(BrokenPipeError):
        shown.done(res)


def test_the_command_shows_its_results_before_its_last_line(tmp_path: Path) -> None:
    out = subprocess.run([sys.executable, "-m", "laboratory.cli", "gyrocompass-test",
                          "--seed", "4", "--out", str(tmp_path / "run")],
                         capture_output=True, text=True, check=True).stdout
    lines = [line for line in out.splitlines() if line.strip()]
    assert lines[-1].endswith(f"record in {tmp_path / 'run'}")
    assert any(line.startswith("truth (eq. 26)") for line in lines[:-1])
    assert sum("operating: theta" in line for line in lines) == 1
