"""A run's plots drawn beside the run (laboratory/plot_worker.py, issue 17): the child
writes the same bytes this process would, and where it cannot, this process draws them."""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

import pytest

from laboratory import plot_worker
from laboratory.plot_worker import PlotWorker, draw_here

RESULTS = "laboratory.isu.plots:results_plot"
ROWS = [{"instrument": f"gyro{k}", "parameter": "R", "units": "deg/hr", "estimate": 1.0 + k,
         "sigma": 0.01, "error": 0.01 * (k - 2), "truth": 1.0, "limit": None}
        for k in (1, 2, 3)]


def test_the_child_writes_what_this_process_writes(tmp_path: Path) -> None:
    with PlotWorker("laboratory.isu.plots") as w:
        w.draw([(RESULTS, {"rows": ROWS, "path": tmp_path / "child.png"})])
        w.wait()
    assert draw_here([(RESULTS, {"rows": ROWS, "path": tmp_path / "here.png"})]) == [None]
    assert (tmp_path / "child.png").read_bytes() == (tmp_path / "here.png").read_bytes()


def test_without_a_child_the_plots_are_drawn_here(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*a: Any, **k: Any) -> None:
        raise OSError("no processes left")

    monkeypatch.setattr(plot_worker.subprocess, "Popen", refuse)
    with PlotWorker() as w:
        w.draw([(RESULTS, {"rows": ROWS, "path": tmp_path / "r.png"})])
        w.wait()
    assert (tmp_path / "r.png").stat().st_size > 1000


def test_a_plot_that_fails_fails_as_it_would_here(tmp_path: Path) -> None:
    """The child reports the failure, this process draws it again and raises its error."""
    with PlotWorker() as w:
        w.draw([(RESULTS, {"rows": [{"error": 1.0, "sigma": 1.0}],
                                  "path": tmp_path / "r.png"})])
        with pytest.raises(KeyError, match="instrument"):
            w.wait()
    assert not (tmp_path / "r.png").exists()


def test_a_run_that_stops_before_waiting_leaves_no_plot(tmp_path: Path) -> None:
    """The child draws to a temporary; only wait() puts the plot in place, so a run that
    stops first (close) ends the child and leaves neither the plot nor a temporary."""
    w = PlotWorker("laboratory.isu.plots")
    proc = w._proc
    assert isinstance(proc, subprocess.Popen)
    w.draw([(RESULTS, {"rows": ROWS, "path": tmp_path / "r.png"})])
    proc.wait()  # the child has drawn (or failed): either way nothing is in place yet
    assert not (tmp_path / "r.png").exists()
    w.close()
    assert proc.poll() is not None
    assert list(tmp_path.iterdir()) == []


def test_an_idle_child_is_ended_at_close_and_a_busy_one_before_close_returns(
        tmp_path: Path) -> None:
    """close: a child that has answered every job is killed and reaped by a thread (the
    run's process need not wait for its teardown); one with a job outstanding is killed
    and reaped before close returns, so nothing it draws can land after close."""
    w = PlotWorker()
    assert w.compute("statistics:fmean", {"data": [1.0, 3.0]})() == 2.0
    idle = w._proc
    assert isinstance(idle, subprocess.Popen)
    w.close()
    assert w._proc is None
    assert idle.wait(timeout=120) == -9  # killed by the thread (not a timing: a bound)
    w = PlotWorker("laboratory.isu.plots")
    busy = w._proc
    assert isinstance(busy, subprocess.Popen)
    w.draw([(RESULTS, {"rows": ROWS, "path": tmp_path / "r.png"})], more=True)
    w.close()  # not answered yet: ended here
    assert busy.poll() is not None
    assert list(tmp_path.iterdir()) == []


def test_a_child_whose_input_ends_exits_at_once_with_zero(tmp_path: Path) -> None:
    """Its input closed (the run gone without a kill), the child answers what it had and
    exits 0 without the interpreter's teardown (laboratory.process_exit.finish)."""
    w = PlotWorker()
    value = w.compute("statistics:fmean", {"data": [2.0, 4.0]})
    p = w._proc
    assert isinstance(p, subprocess.Popen) and p.stdin is not None
    p.stdin.close()
    assert value() == 3.0
    assert p.wait(timeout=120) == 0
    w.close()


def test_a_plot_beside_a_record_file_of_its_stem_leaves_it_alone(tmp_path: Path) -> None:
    """results.png drawn while results.json is written: neither clears the other's
    temporary (atomic_path clears ``.results.tmp-*`` of a killed writer)."""
    from station.files import atomic_path

    with atomic_path(tmp_path / "results.json") as tmp_json:
        tmp_json.write_text("{}")
        assert draw_here([(RESULTS, {"rows": ROWS, "path": tmp_path / "results.png"})]) == [None]
        assert tmp_json.exists()
    with atomic_path(tmp_path / "results.json") as tmp_json:  # and the other way round
        for old in tmp_path.glob(".results.png.plot-*"):  # a plot being drawn
            raise AssertionError(f"{old} left behind")
        (tmp_path / ".results.png.plot-1.png").write_bytes(b"png")
        tmp_json.write_text("[]")
        with atomic_path(tmp_path / "results.json") as again:
            again.write_text("[]")
    assert (tmp_path / ".results.png.plot-1.png").exists()
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == [
        "results.json", "results.png"]


def test_meanwhile_runs_once_before_the_plots_are_in_place(tmp_path: Path) -> None:
    """wait(meanwhile=...) runs the caller's next work while the child may still draw
    (a run prepares its report's template there): once, before any plot is installed."""
    seen: list[bool] = []
    with PlotWorker("laboratory.isu.plots") as w:
        w.draw([(RESULTS, {"rows": ROWS, "path": tmp_path / "r.png"})])
        w.wait(meanwhile=lambda: seen.append((tmp_path / "r.png").exists()))
    assert seen == [False]
    assert (tmp_path / "r.png").stat().st_size > 1000


def test_a_child_started_early_is_the_runs_and_draws_what_it_lacks(tmp_path: Path) -> None:
    """start_early (the station script, as the command line names the command): the run's
    PlotWorker adopts that child, which imports at the first job a module it was not
    started with (here the ISU's plots in a child warmed for the CIGTF's)."""
    plot_worker.start_early("laboratory.cigtf.plots")
    early = plot_worker._early
    assert isinstance(early, subprocess.Popen)
    with PlotWorker("laboratory.isu.plots") as w:
        assert w._proc is early
        assert plot_worker._early is None  # adopted once: a second worker starts its own
        w.draw([(RESULTS, {"rows": ROWS, "path": tmp_path / "child.png"})])
        w.wait()
    assert early.poll() is not None
    assert draw_here([(RESULTS, {"rows": ROWS, "path": tmp_path / "here.png"})]) == [None]
    assert (tmp_path / "child.png").read_bytes() == (tmp_path / "here.png").read_bytes()


def test_an_early_child_no_run_adopted_is_ended_at_exit() -> None:
    """A command refused before its run (a bad argument) leaves no child: the exit handler
    kills it (it waits on its stdin, which this process holds open, so only the kill ends
    it)."""
    plot_worker.start_early("laboratory.isu.plots")
    early = plot_worker._early
    assert isinstance(early, subprocess.Popen)
    plot_worker._end_early()  # what the exit handler runs
    assert early.returncode == -9
    assert plot_worker._early is None


def test_the_script_starts_the_child_its_command_declares() -> None:
    """laboratory.cli.start_plot_child: the day's, the gyrocompassing test's and the ESG
    calibration's commands declare their children's modules; a help or another command
    starts none."""
    from laboratory import cli
    from laboratory.app import PLOT_CHILDREN

    assert PLOT_CHILDREN["day"] == ("laboratory.isu.plots",
                                    "procedures.isu.calibration.all_positions")
    assert PLOT_CHILDREN["gyrocompass-test"] == ("laboratory.cigtf.plots",)
    assert "laboratory.esg.study" in PLOT_CHILDREN["esg-calibration"]
    for args in ([], ["day", "--help"], ["check"], ["esg-calibration", "-h"]):
        cli.start_plot_child(args)
        assert plot_worker._early is None, args
    cli.start_plot_child(["gyrocompass-test", "--seed", "3"])
    early = plot_worker._early
    assert isinstance(early, subprocess.Popen)
    assert early.args[-1] == "laboratory.cigtf.plots"  # type: ignore[index]
    plot_worker._end_early()


def test_a_computation_is_the_childs_value_or_computed_here(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """compute: a job without a file; its value comes from the child, or, where the child
    cannot be started, is computed here; an error is raised here, as the run's own; a
    computation leaves no file and needs no wait."""
    job = "statistics:fmean"
    with PlotWorker() as w:
        later = w.compute(job, {"data": [1.0, 2.0, 4.0]})
        bad = w.compute(job, {"data": []})
        w.draw([(RESULTS, {"rows": ROWS, "path": tmp_path / "r.png"})])
        assert later() == pytest.approx(7.0 / 3.0)
        assert 0 not in w._here
        with pytest.raises(Exception, match="mean requires at least one data point"):
            bad()
        w.wait()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.png"]

    def refuse(*a: Any, **k: Any) -> None:
        raise OSError("no processes left")

    monkeypatch.setattr(plot_worker.subprocess, "Popen", refuse)
    with PlotWorker() as w:
        assert w._proc is None
        xs = [2.0, 4.0]
        later = w.compute(job, {"data": xs})
        xs.append(12.0)  # changed after the call: computed here on the arguments then
        assert later() == 3.0
        w.wait()


def test_the_child_pins_its_blas_as_the_run_does(monkeypatch: pytest.MonkeyPatch) -> None:
    """A value computed in the child is the same bits as here: the child limits its BLAS to
    one thread (station.numerics.pin_blas_threads), whatever this process was started
    with (the early child starts before any run pins anything)."""
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    with PlotWorker() as w:
        n = w.compute("os:getenv", {"key": "OPENBLAS_NUM_THREADS"})()
        w.wait()
    assert n == "1"


def test_the_days_nonlinearity_plot_goes_once_as_soon_as_chart_ii7_has_run(
        tmp_path: Path) -> None:
    """laboratory.isu.day.NonlinearityPlot: sent when Chart II-7's block is heard (its data
    by position, as measure_day loads them), not again after the measurements; sent then
    when II-7 was not heard (restored, or not measured)."""
    from laboratory.isu.day import NonlinearityPlot

    class Plotter:
        def __init__(self) -> None:
            self.sent: list[Any] = []

        def draw(self, jobs: list[Any], more: bool = False) -> int:
            self.sent.append((jobs, more))
            return len(self.sent) - 1

    p = Plotter()
    plot = NonlinearityPlot(p, None, tmp_path / "n.png")  # type: ignore[arg-type]
    plot.chart_done({"kind": "step", "chart": "II-7"})
    plot.chart_done({"kind": "block", "key": "II-6", "data": {"data": {}}})
    assert p.sent == []
    plot.chart_done({"kind": "block", "key": "II-7", "data": {"data": {"1": [{"x": 1}]}}})
    plot.send({})  # the measurements' end: already sent
    ((jobs, more),) = p.sent
    assert more and jobs[0][1]["points"] == {1: [{"x": 1}]}
    late = Plotter()
    NonlinearityPlot(late, None, tmp_path / "n.png").send({3: []})  # type: ignore[arg-type]
    assert late.sent[0][0][0][1]["points"] == {3: []}


def test_a_computation_the_child_dropped_is_computed_on_its_arguments_as_sent() -> None:
    """A child that dies after taking a computation: the value is computed here on the
    arguments as they were at the call, not as the run has changed them since."""
    with PlotWorker() as w:
        xs = [1.0, 3.0]
        later = w.compute("statistics:fmean", {"data": xs})
        xs.append(20.0)
        proc = w._proc  # still importing matplotlib: it has not taken the job yet
        assert isinstance(proc, subprocess.Popen) and proc.poll() is None
        proc.kill()
        proc.wait()
        assert later() == 2.0
        assert 0 in w._here
        w.wait()


def test_a_batch_after_the_last_is_drawn_here(tmp_path: Path) -> None:
    """After the batch sent as the last (the child's stdin closed) a further plot or
    computation is not written to the closed pipe (a ValueError before): wait draws the
    plot here and the computation is computed here."""
    with PlotWorker() as w:
        w.draw([(RESULTS, {"rows": ROWS, "path": tmp_path / "a.png"})])
        w.draw([(RESULTS, {"rows": ROWS, "path": tmp_path / "b.png"})])
        assert w.compute("statistics:fmean", {"data": [1.0, 5.0]})() == 3.0
        w.wait()
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()


def test_the_days_sheets_written_by_an_idle_child_or_here(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """laboratory.isu.day.sheets_beside: the sheet files are those write_sheets writes,
    whether an idle child wrote them, a busy one after its work, or the child died after
    taking them (written here on the values as they were)."""
    import simpy

    from laboratory.isu.day import sheets_beside
    from laboratory.record import write_sheets
    from procedures.journal import Journal
    from procedures.runner import Run
    from station.clock import VirtualClock

    run = Run(VirtualClock(simpy.Environment()), Journal(tmp_path / "j.jsonl"))
    run.sheets["a"] = {"x": [1.5, 2], "y": "text"}
    run.sheets["b"] = {"nested": {"z": None}}
    write_sheets(tmp_path / "ref", run)
    expect = {p.name: p.read_bytes() for p in (tmp_path / "ref" / "sheets").iterdir()}

    def written(out: Path) -> dict[str, bytes]:
        return {p.name: p.read_bytes() for p in (out / "sheets").iterdir()}

    with PlotWorker() as w:  # idle (nothing sent): the child writes them
        w.compute("statistics:fmean", {"data": [1.0]})()
        done = sheets_beside(w, tmp_path / "idle", run)
        assert 1 in w._sent  # handed over
        done()
        assert 1 not in w._here
        w.wait()
    assert written(tmp_path / "idle") == expect
    with PlotWorker() as w:  # busy: written after what it does (most sheets are staged)
        w.compute("subprocess:run", {"args": ["sleep", "0.5"]})
        done = sheets_beside(w, tmp_path / "busy", run)
        done()
        assert written(tmp_path / "busy") == expect
        w.wait()
    with PlotWorker() as w:  # a sheet pickle cannot carry: written here at once
        run.sheets["c"] = {"f": lambda: None}
        with pytest.raises(TypeError):  # not JSON either: the run's own error, as before
            sheets_beside(w, tmp_path / "unpicklable", run)
        del run.sheets["c"]
        w.wait()
    with PlotWorker() as w:  # the child dies after taking them: written here
        w.compute("statistics:fmean", {"data": [1.0]})()
        done = sheets_beside(w, tmp_path / "died", run)
        run.sheets["a"] = {"changed": True}  # after the call: not what is written
        proc = w._proc
        assert isinstance(proc, subprocess.Popen)
        proc.kill()
        proc.wait()
        done()
        w.wait()
    run.sheets["a"] = {"x": [1.5, 2], "y": "text"}
    assert written(tmp_path / "died") == expect
    run.journal.close()


def test_an_answer_come_behind_another_is_seen_at_once(tmp_path: Path) -> None:
    """Two answers in the pipe back to back: reading the first leaves the second in the
    pipe (read by exact length), so a raced computation sees it has come and takes the
    child's value instead of computing it again here (a buffered read took both, and the
    second then read as not come)."""
    import select
    import time

    flag = tmp_path / "second-done"
    with PlotWorker() as w:
        first = w.compute("statistics:fmean", {"data": [1.0, 3.0]})
        second = w.compute("subprocess:run", {"args": ["touch", str(flag)]}, race=True)
        proc = w._proc
        assert isinstance(proc, subprocess.Popen) and proc.stdout is not None
        while not flag.exists():  # the child has run the second job
            time.sleep(0.01)
        while True:  # and both answers are in the pipe (the second follows the touch)
            time.sleep(0.05)
            if select.select([proc.stdout], [], [], 0.0)[0] and w._answered == 0:
                break
        assert first() == 2.0
        assert w._answered == 1  # the first read, the second left where select sees it
        flag.unlink()
        assert second().returncode == 0
        assert not w._here and not flag.exists()  # the child's answer: not run again here
        w.wait()


def test_the_days_sheets_rendered_beside_are_the_files_written_here(tmp_path: Path) -> None:
    """laboratory.isu.day.SheetsRendered and sheets_beside: sheets rendered by the child as
    they were saved, one changed after and one added, are written as write_sheets writes
    the run's final sheets (the changed one from its new model, not the rendered one)."""
    import simpy

    from laboratory.isu.day import SheetsRendered, sheets_beside
    from laboratory.record import write_sheets
    from procedures.journal import Journal
    from procedures.runner import Run
    from station.clock import VirtualClock

    run = Run(VirtualClock(simpy.Environment()), Journal(tmp_path / "j.jsonl"))
    run.sheets["a"] = {"x": [1.5, 2], "y": "text"}
    run.sheets["b"] = {"nested": {"z": None}}
    out = tmp_path / "beside"
    out.mkdir()
    with PlotWorker() as w:
        rendered = SheetsRendered(w, out)
        rendered({"kind": "sheet", "name": "a", "data": run.sheets["a"]})  # not started
        rendered.start(run)
        run.sheets["c"] = {"late": [0.1, 0.2]}
        rendered({"kind": "sheet", "name": "c", "data": run.sheets["c"]})
        run.sheets["b"] = {"nested": {"z": 3.25}}  # changed after it was rendered
        assert w.values(len(w._batches) - 1) == [None]  # the renders are done
        assert sorted(p.name for p in out.iterdir()) == [
            f".sheets-stage.{n}.json" for n in ("a", "b", "c")]  # staged, none in sheets/
        done = sheets_beside(w, out, run)
        done()
        w.wait()
    assert sorted(p.name for p in out.iterdir()) == ["sheets"]  # no stage left
    write_sheets(tmp_path / "ref", run)
    for name in ("a", "b", "c"):
        got = (tmp_path / "beside" / "sheets" / f"{name}.json").read_bytes()
        assert got == (tmp_path / "ref" / "sheets" / f"{name}.json").read_bytes()
    assert b"3.25" in (tmp_path / "beside" / "sheets" / "b.json").read_bytes()
    run.journal.close()


def test_a_send_to_a_child_blocked_on_its_answer_does_not_wait_for_it() -> None:
    """A child whose answer fills its output pipe (the run has not read it yet) still
    takes the batches sent after it, so the run's send returns and the run, reading the
    answer later, gets both values. Before the child read ahead, both processes waited on
    each other for ever: the day hung whenever its plot child lagged where the pipe to it
    could not be widened (the widening then went: no longer needed)."""
    answer_bytes = 1 << 20  # past a pipe: the child blocks writing it
    sent = "x" * (2 << 20)  # past a pipe: the send waits for a reader
    with PlotWorker() as w:
        big = w.compute("secrets:token_bytes", {"nbytes": answer_bytes})
        quoted = w.compute("json:dumps", {"obj": sent})  # returns only if the child reads
        assert quoted() == f'"{sent}"'
        assert len(big()) == answer_bytes
        assert not w._here  # both the child's values, none computed here
        w.wait()
