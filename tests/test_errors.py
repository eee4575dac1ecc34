"""One root of operator-facing errors (station/errors.py): every class the operator can be
shown is an OperatorError whose exit code says which family it belongs to (2: the command
was not run as asked; 1: a procedure stopped); a failed check carries its chart and step;
the command line ends on any of them with one line and that code."""

from __future__ import annotations

import ast
import importlib
import inspect
import json
import pkgutil
from pathlib import Path

import pytest
import simpy
from typer.testing import CliRunner

from instruments.isu.table_controller import TableController
from laboratory.apply import RawFileError
from laboratory.calfile import CalibrationFileError
from laboratory.campaign.spec import SpecError
from laboratory.cli import app
from laboratory.history.store import HistoryError
from laboratory.registry import UnknownLaboratory
from laboratory.report.html import ReportError
from laboratory.rundir import RunComplete, RunDirError
from procedures.esg.readings import TooFewLines
from procedures.isu.alignment.preprocess import MissingConstants
from procedures.isu.plausibility import Implausible
from procedures.journal import Journal, JournalError
from procedures.runner import ProcedureError, ResumeMismatch, Run
from station.clock import VirtualClock
from station.config.file import ConfigError
from station.drivers.isu.ieu import FailedCheck, GarbledFrame
from station.errors import (
    BadArgument,
    CheckFailed,
    Deadlock,
    DriverError,
    InstrumentRefused,
    LinkTimeout,
    MalformedReply,
    OperatorError,
    ReadingOutOfRange,
    StationError,
    StepName,
    StopError,
    UseError,
    VerdictFailed,
    current_step,
)
from station.hil.links_dir import LinksDirError
from station.hil.profile import NoServedRack, WrongStation

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("sim", "instruments", "station", "procedures", "laboratory")

# every operator-facing class and its exit code (docs/ARCHITECTURE.md, "Errors and exit codes")
EXIT_CODES: dict[type[OperatorError], int] = {
    BadArgument: 2, ConfigError: 2, RunDirError: 2, JournalError: 2, ResumeMismatch: 2,
    NoServedRack: 2, WrongStation: 2, UnknownLaboratory: 2, ReportError: 2,
    CalibrationFileError: 2, RawFileError: 2,  # `station apply` (laboratory/calfile.py)
    HistoryError: 2, SpecError: 2,  # `station campaign` (laboratory/campaign/spec.py)
    RunComplete: 0,  # --resume of a finished run: nothing to do, said on stdout
    CheckFailed: 1, Implausible: 1, TooFewLines: 1, ProcedureError: 1, DriverError: 1,
    LinkTimeout: 1, MalformedReply: 1, ReadingOutOfRange: 1, InstrumentRefused: 1,
    GarbledFrame: 1, FailedCheck: 1, Deadlock: 1,
    VerdictFailed: 3,  # completed, a result row outside its limit (laboratory/verdicts.py)
}
ROOTS = {OperatorError, UseError, StopError, StationError}
# exception classes that are not OperatorErrors, and why
NOT_OPERATOR_ERRORS = {
    "sim.isu.table.TableError": "the simulated table's refusal, answered as an ERR reply",
    "instruments.base.InstrumentError": "an instrument's refusal, sent as an ERR reply "
                                        "(the driver raises InstrumentRefused)",
    "station.drivers.replies.OutOfRange": "a reply parser's finding; the driver raises "
                                          "ReadingOutOfRange",
    "station.drivers.replies.Malformed": "a reply parser's finding; the driver raises "
                                         "MalformedReply",
    "station.hil.link_map.BadLinkMap": "read by profile.served, which raises NoServedRack",
    "station.hil.session.BadSession": "read by profile.served, which raises NoServedRack",
    # ValueErrors met at a command's boundary, which turns them into exit 2
    "station.hil.links_dir.LinksDirError": "a ValueError `station serve` refuses (exit 2)",
    "procedures.isu.accuracy.Unreachable":
        "a ValueError `station day` meets before anything is written (exit 2)",
    "procedures.isu.alignment.preprocess.MissingConstants":
        "a ValueError the day catches to leave an alignment out; inside a step it stops it",
}


def defined_exceptions() -> set[type[BaseException]]:
    """Every exception class defined in the project's packages."""
    found: set[type[BaseException]] = set()
    for pkg in PACKAGES:
        root = importlib.import_module(pkg)
        for info in pkgutil.walk_packages(root.__path__, f"{pkg}."):
            module = importlib.import_module(info.name)
            found |= {c for c in vars(module).values() if inspect.isclass(c)
                      and issubclass(c, BaseException) and c.__module__ == module.__name__}
    return found


# ----------------------------------------------------------------------------- the hierarchy


@pytest.mark.parametrize("cls", EXIT_CODES, ids=lambda c: c.__name__)
def test_each_operator_error_has_its_familys_exit_code(cls):
    code = EXIT_CODES[cls]
    assert issubclass(cls, OperatorError) and cls.exit_code == code
    assert issubclass(cls, UseError) == (code in (0, 2))
    assert issubclass(cls, StopError) == (code == 1)


def test_every_exception_class_is_an_operator_error_or_says_why_not():
    classes = defined_exceptions()
    names = {f"{c.__module__}.{c.__qualname__}" for c in classes}
    assert names >= set(NOT_OPERATOR_ERRORS)
    unplaced = {c for c in classes if c not in EXIT_CODES and c not in ROOTS
                and f"{c.__module__}.{c.__qualname__}" not in NOT_OPERATOR_ERRORS}
    assert not unplaced, f"give these an exit code (or a reason): {unplaced}"
    assert all(issubclass(c, OperatorError) for c in set(EXIT_CODES) | ROOTS)
    assert not any(issubclass(c, OperatorError) for c in classes
                   if f"{c.__module__}.{c.__qualname__}" in NOT_OPERATOR_ERRORS)


def test_old_bases_and_messages_are_kept():
    # callers that catch the builtin still catch these
    assert issubclass(ConfigError, ValueError) and issubclass(WrongStation, ValueError)
    assert issubclass(NoServedRack, FileNotFoundError)
    assert issubclass(LinksDirError, ValueError) and issubclass(MissingConstants, ValueError)
    # a failed check is no RuntimeError (no `except RuntimeError` takes it for another error)
    assert not issubclass(CheckFailed, RuntimeError)
    msg = "no served rack under runs/links (is `station serve` running?)"
    assert str(NoServedRack(msg)) == msg and NoServedRack(msg).args == (msg,)
    assert str(ConfigError("c.toml: bad")) == "c.toml: bad"
    assert str(Implausible("table (sim://table)", "interlock 'OPEN'")) == \
        "table (sim://table): interlock 'OPEN'"
    assert str(ProcedureError("I-1", "6", "Table interlock closed", "why")) == \
        "Chart I-1, step 6 (Table interlock closed): why"


# ----------------------------------------------------------------------------- chart and step


@pytest.fixture
def run(tmp_path):
    return Run(VirtualClock(simpy.Environment()), Journal(tmp_path / "journal.jsonl"))


def test_a_failed_check_in_a_step_carries_it_and_stops_the_procedure_there(run):
    with pytest.raises(ProcedureError) as e, run.sheet("II-6", "Gyro rotating") as sheet:
        sheet.done("8", "warm-up")
        with sheet.step("9/m1", "count the gyro"):
            raise CheckFailed("count 2443 where 2453 was read")
    err, cause = e.value, e.value.__cause__
    assert isinstance(cause, CheckFailed)
    assert (cause.chart, cause.step) == (err.chart, err.step) == ("II-6", "9/m1")
    assert err.cause == str(cause) == "count 2443 where 2453 was read"
    assert str(err) == "Chart II-6, step 9/m1 (count the gyro): count 2443 where 2453 was read"
    recs = [json.loads(x) for x in run.journal.path.read_text().splitlines()]
    assert recs[-1]["kind"] == "failed" and (recs[-1]["chart"], recs[-1]["step"]) == \
        ("II-6", "9/m1")


def test_a_failed_check_names_the_innermost_step_and_nothing_outside_one(run):
    with run.sheet("I-1", "Turn-on") as sheet, sheet.step("6", "interlock closed"):
        inner = Implausible("table (sim://table)", "interlock 'OPEN': motion inhibited")
        named = CheckFailed("given", chart="III-4", step="9")  # an explicit place wins
    assert (inner.chart, inner.step) == ("I-1", "6")
    assert (named.chart, named.step) == ("III-4", "9")
    outside = TooFewLines("fewer than 5 usable lines")
    assert (outside.chart, outside.step) == (None, None) and current_step.get() is None


def test_the_step_name_reads_as_before_and_keeps_chart_and_step(run):
    with run.sheet("I-1", "Turn-on") as sheet, sheet.step("4", "counters"):
        at = current_step.get()
        err = LinkTimeout("counter3", "sim://counter3", "no reply to 'STAT?'")
    assert at == "Chart I-1 step 4" and isinstance(at, StepName)
    assert (at.chart, at.step) == ("I-1", "4")
    assert err.step == "Chart I-1 step 4"
    assert str(err) == "counter3 (sim://counter3) during Chart I-1 step 4: no reply to 'STAT?'"


# ----------------------------------------------------------------------------- the command line


@pytest.fixture
def cli(tmp_path, monkeypatch):
    """`station ...` in-process from an empty working directory."""
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    return lambda *args: runner.invoke(app, [str(a) for a in args])


def test_a_day_stopped_by_a_failed_check_exits_1_naming_chart_and_step(cli, tmp_path,
                                                                        monkeypatch):
    """The table's interlock left open: turn-on's step 6 check fails (Implausible)."""
    init = TableController.__init__

    def open_interlock(self, *args, **kwargs):
        init(self, *args, **kwargs)
        self.interlock_closed = False

    monkeypatch.setattr(TableController, "__init__", open_interlock)
    out = tmp_path / "D"
    r = cli("day", "--seed", 3, "--only", "II-11", "--positions", 7, "--out", out, "--quiet")
    assert r.exit_code == 1, r.output
    assert r.stderr.count("\n") == 1
    assert r.stderr.startswith("stopped: Chart I-1, step 6 (Table interlock closed (safe to "
                               "move)): table (sim://table")
    assert "): interlock 'OPEN': motion inhibited (the journal keeps" in r.stderr
    assert f"continue with --resume {out})" in r.stderr
    recs = [json.loads(x) for x in (out / "journal.jsonl").read_text().splitlines()]
    assert recs[-1]["kind"] == "failed" and (recs[-1]["chart"], recs[-1]["step"]) == ("I-1", "6")
    assert ("I-1", "5") in {(x["chart"], x["step"]) for x in recs if x["kind"] == "step"}


def test_a_failed_check_outside_any_step_is_a_stop_not_a_traceback(cli, tmp_path,
                                                                   monkeypatch):
    def stops(*args, **kwargs):
        raise CheckFailed("turn-on (Chart I-1) step 3 has not recorded the oscillator's "
                          "countdowns in this run")

    monkeypatch.setattr("laboratory.isu.day.run_day", stops)
    r = cli("day", "--out", tmp_path / "D")
    assert r.exit_code == 1 and isinstance(r.exception, SystemExit), r.exception
    assert r.stderr.count("\n") == 1
    assert r.stderr.startswith("stopped: turn-on (Chart I-1) step 3 has not recorded")


@pytest.mark.parametrize(("args", "words"), [
    (("day", "--only", "II-99"), "--only: unknown chart(s) II-99"),  # a builtin ValueError
    (("day", "--seed", "-1"), "--seed must be 0 or more, got -1"),  # the CLI's own refusal
    (("day", "--config", "missing.toml"), "--config: configuration file not found"),
    (("align", "--resume", "nowhere"), "--resume nowhere: no such directory"),  # RunDirError
    (("esg-calibration", "--resume", "nowhere"), "--resume nowhere: no such directory"),
])
def test_an_error_of_use_exits_2_with_one_line(cli, args, words):
    r = cli(*args)
    assert r.exit_code == 2, r.output
    assert r.stdout == "" and r.stderr.count("\n") == 1
    assert r.stderr.startswith("error: ") and words in r.stderr


def test_resuming_a_finished_run_says_so_and_exits_0(cli, tmp_path):
    d = tmp_path / "R"
    d.mkdir()
    start = {"kind": "note", "event": "start", "command": "esg-calibration", "seed": 1}
    end = {"kind": "note", "event": "end"}
    (d / "journal.jsonl").write_text("".join(json.dumps(x) + "\n" for x in (start, end)))
    r = cli("esg-calibration", "--resume", d)
    assert r.exit_code == 0 and r.stderr == "", r.output
    assert r.stdout.strip() == f"{d}: that run is complete (its journal holds the end note): " \
                               "nothing to resume"


# ----------------------------------------------------------------------------- no bare errors


def test_procedures_raise_no_runtime_error():
    """A failed check is CheckFailed; a programming error a fitting builtin."""
    found = []
    for path in sorted((REPO / "procedures").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            exc = node.exc if isinstance(node, ast.Raise) else None
            name = exc.func if isinstance(exc, ast.Call) else exc
            if isinstance(name, ast.Name) and name.id == "RuntimeError":
                found.append(f"{path.relative_to(REPO)}:{node.lineno}")
            if isinstance(node, ast.ClassDef) and any(
                    isinstance(b, ast.Name) and b.id == "RuntimeError" for b in node.bases):
                found.append(f"{path.relative_to(REPO)}:{node.lineno} (class)")
    assert not found, found
