"""The garbage collector deferred while a run command imports (laboratory.startup, issue 17):
off only between the script's start and the run's connect, on for everything else."""

from __future__ import annotations

import gc
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from laboratory import registry, startup
from laboratory.connect import connect
from laboratory.seeded import Seeded
from sim.cigtf.world import CigtfParams


@pytest.fixture
def collector() -> Iterator[None]:
    """The test process's collector as it was, whatever the test does to it."""
    gc.collect()  # nothing of earlier tests frozen with what resume freezes
    was = gc.isenabled()
    try:
        yield
    finally:
        startup.resume()
        gc.unfreeze()
        (gc.enable if was else gc.disable)()


def test_resume_without_defer_leaves_the_collector_alone(collector: None) -> None:
    gc.disable()
    startup.resume()
    assert not gc.isenabled()  # a process that never deferred: not this module's to turn on
    gc.enable()
    startup.resume()
    assert gc.isenabled() and gc.get_freeze_count() == 0


def test_a_run_turns_the_deferred_collector_on_when_it_connects(collector: None) -> None:
    startup.defer()
    assert not gc.isenabled()
    conn = connect(registry.get("cigtf"), Seeded(CigtfParams(), 1))
    try:
        assert gc.isenabled()
        assert gc.get_freeze_count() > 0  # the imports' objects, skipped by later passes
    finally:
        conn.close()
    startup.resume()  # once only: nothing more to do
    assert gc.isenabled()


def test_a_refused_connection_turns_it_on_too(collector: None) -> None:
    startup.defer()
    with pytest.raises(ValueError):
        connect(registry.get("cigtf"), Seeded(CigtfParams(), 1), start_s=1.0,
                links_dir=Path("/nonexistent"))
    assert gc.isenabled()


@pytest.mark.parametrize(("command", "during"), [("history", True), ("day", False),
                                                 ("esg-calibration", False)])
def test_the_script_defers_it_for_a_run_only(command: str, during: bool) -> None:
    """What the command's own code sees: on at once for any command but a run, whose
    connect turns it on (the command's main replaced by a probe; a run's early plot child
    is ended at exit)."""
    code = ("import gc, sys\n"
            "import laboratory.cli as cli\n"
            "cli.main = lambda: print('collector', gc.isenabled())\n"
            f"sys.argv = ['station', {command!r}]\n"
            "import laboratory.script as script\n"
            "script.run()\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True).stdout
    assert f"collector {during}" in out


def test_the_plot_child_defers_it_while_it_imports_and_then_collects() -> None:
    """The plot child (laboratory.plot_worker.main) does as the script: on again after its
    imports, which are frozen; asked in the child itself (no job drawn here)."""
    from laboratory.plot_worker import PlotWorker

    with PlotWorker("laboratory.cigtf.plots") as w:
        enabled = w.compute("gc:isenabled", {})
        frozen = w.compute("gc:get_freeze_count", {})
        assert enabled() is True and frozen() > 0
        assert not w._here  # both answered by the child  # noqa: SLF001
