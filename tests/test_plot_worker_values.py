"""A plot job that also returns what the run records (laboratory/plot_worker.py, issue 17):
the ESG strategy study computed and drawn by the child equals the study computed here, its
plot the same bytes; without a child it is computed and drawn here."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import pytest

from laboratory import plot_worker
from laboratory.esg.study import study, study_plot
from laboratory.plot_worker import PlotWorker

JOB = "laboratory.esg.study:study_plot"


def test_the_child_returns_the_study_and_draws_its_plot(tmp_path: Path) -> None:
    with PlotWorker("laboratory.esg.study") as w:
        first = w.draw([(JOB, {"path": tmp_path / "child.png"})], more=True)
        (value,) = w.values(first)
        assert not (tmp_path / "child.png").exists()  # put in place only by wait()
        w.wait()
    assert value == study()
    assert study_plot(tmp_path / "here.png") == value
    assert (tmp_path / "child.png").read_bytes() == (tmp_path / "here.png").read_bytes()


def test_without_a_child_the_study_is_computed_here(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*a: Any, **k: Any) -> None:
        raise OSError("no processes left")

    monkeypatch.setattr(plot_worker.subprocess, "Popen", refuse)
    with PlotWorker() as w:
        first = w.draw([(JOB, {"path": tmp_path / "s.png"})], more=True)
        (value,) = w.values(first)
        w.wait()
    assert value == study() and (tmp_path / "s.png").stat().st_size > 1000


def test_a_race_does_not_wait_for_a_busy_child(tmp_path: Path) -> None:
    """Run.meanwhile's computations (race): a child still busy with what was sent before
    (here held until a file appears) does not hold the run up; the value is made here, and
    the child's answer, once it comes, is read and left. A child that has answered gives
    its value."""
    gate = tmp_path / "gate"
    with PlotWorker() as w:
        w.compute("subprocess:run",
                  {"args": ["sh", "-c", f"while [ ! -e '{gate}' ]; do sleep 0.01; done"]})
        raced = w.compute("json:dumps", {"obj": [1, 2]}, race=True)
        assert raced() == "[1, 2]"
        assert w._outcomes[-1] is None and 1 in w._here  # made here: the child is held
        gate.touch()
        later = w.compute("json:dumps", {"obj": [3]}, race=True)
        w.values(2)  # the child has answered all three now
        assert later() == "[3]" and 2 not in w._here and w._outcomes[2] == ("ok", "[3]")
        w.wait()


def test_a_race_waits_for_a_child_already_on_it(tmp_path: Path) -> None:
    """A raced computation the child has begun (it answered every batch before) is awaited,
    not made again here: the child began it no later than this process would."""
    gate, began = tmp_path / "gate", tmp_path / "began"
    with PlotWorker() as w:
        w.compute("json:dumps", {"obj": [0]})()  # answered: the child is free
        raced = w.compute("subprocess:run", {"args": [
            "sh", "-c", f"touch '{began}'; while [ ! -e '{gate}' ]; do sleep 0.01; done; "
                        "echo child"], "capture_output": True, "text": True}, race=True)
        while not began.exists():  # the child is on it
            time.sleep(0.01)
        threading.Timer(0.3, gate.touch).start()  # released only while this one waits
        assert raced().stdout == "child\n"
        assert 1 not in w._here and w._outcomes[1] is not None
        w.wait()
