"""Running a procedure as the laboratory does: check-sheets ticked step by step, journaled.

Every completed step is one journal record (chart, step number, text, simulated time,
reading). A failing step stops its procedure with ``ProcedureError`` naming the chart and
step; everything recorded before it stays in the journal.

Resume has two modes. ``replay`` (virtual time): a run opened on an existing journal
re-executes the procedures from the start and checks each step it repeats against the
journal (in virtual time this replay is exact and takes seconds), then goes on appending;
a mismatch means the seed, the config or the code changed, and is refused. ``skip`` (real
time, over links, where repeating hours of measurement is not an option and readings are
never bit-identical): each whole chart run through :meth:`Run.block` journals its result;
a completed chart is restored from the journal with the sheets it saved, and the first
incomplete chart is repeated from its first step (its earlier partial steps stay in the
journal as history). ``repeat`` names blocks to run again even if completed (turn-on after
the rack was power-cycled); its entries are shell-style patterns (``ESG-CAL.scan-*``).
A block may also cover some steps of an open check-sheet (the ESG's scans are steps of one
sheet): those steps are journaled with the block and put back on the sheet when it is
restored.
"""

from __future__ import annotations

import datetime as dt
import json
import pickle
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from fnmatch import fnmatchcase
from functools import cache
from importlib import import_module
from typing import Any, Protocol, TypeVar

from pydantic import BaseModel, ValidationError

from procedures.journal import Journal, JournalError, dumps
from procedures.sheets import SHEET_MODELS, CheckSheet, Sheet, SheetHeader, StepRecord
from station.clock import Clock
from station.errors import StepName, StopError, UseError, current_step
from station.numerics import pin_blas_threads

VOLATILE = ("wall",)
RESUME_MODES = ("replay", "skip")
T = TypeVar("T")


class ProcedureError(StopError):
    """A step that could not be completed; the message names the chart and the step (exit 1)."""

    def __init__(self, chart: str, step: str, text: str, cause: str) -> None:
        self.chart, self.step, self.cause = chart, step, cause
        super().__init__(f"Chart {chart}, step {step} ({text}): {cause}")


class ResumeMismatch(UseError):
    """The replayed run does not reproduce the journal it resumes (exit 2: the journal is
    another run's)."""


def _stable(rec: dict) -> dict:
    """A record as a replay compares it: no wall stamp, and no sheet header (the run's
    identity, not a measurement: a resume by another operator on another day is the same
    run)."""
    out = {k: v for k, v in json.loads(dumps(rec)).items() if k not in VOLATILE}
    if isinstance(out.get("data"), dict):
        out["data"] = {k: v for k, v in out["data"].items() if k != "header"}
    return out


def _sheet_value(journal: Journal, rec: dict, line: int,
                 models: Mapping[str, type[Sheet]]) -> Any:
    """A journaled sheet as its model (plain data if it has none); JournalError naming the
    line when the data is not such a sheet."""
    name = rec["name"]
    model = models.get("check" if name.startswith("check_") else name)
    if model is None:
        return rec["data"]
    try:
        return model.model_validate(rec["data"])
    except ValidationError as e:
        err = e.errors()[0]
        where = ".".join(str(x) for x in err["loc"]) or "(top)"
        raise JournalError(f"{journal.path}:{line}: sheet {name!r} is not a valid "
                           f"{model.__name__}: {where}: {err['msg']}") from None


class Beside(Protocol):
    """A second process the run hands computations to (laboratory.plot_worker.PlotWorker)."""

    def compute(self, job: str, kwargs: dict[str, Any], race: bool = False
                ) -> Callable[[], Any]: ...


class StepContext:
    def __init__(self) -> None:
        self.reading: Any = None


class Run:
    """The journal, the completed check-sheets and the sheets of one run."""

    def __init__(
        self,
        clock: Clock,
        journal: Journal,
        listener: Callable[[dict], None] | None = None,
        resume: str = "replay",
        repeat: tuple[str, ...] = (),
        sheet_models: Mapping[str, type[Sheet]] = SHEET_MODELS,
        header: Mapping[str, Any] | None = None,
        sheets_used: Callable[[str], list[str]] | None = None,
        beside: Beside | None = None,
    ) -> None:
        """``sheet_models``: the laboratory's sheet models by name, to restore its sheets
        from the journal (skip mode) as models rather than plain data. ``header``: the
        heading every new sheet with a ``header`` field gets (SheetHeader's fields; None:
        no headers); ``sheets_used(name)`` its "Sheet Used" cross-references by sheet name
        (``check_<chart>`` for a check-sheet). ``beside``: where ``meanwhile`` computes
        (None: here, at the call)."""
        if resume not in RESUME_MODES:
            raise ValueError(f"resume mode must be one of {RESUME_MODES}, got {resume!r}")
        pin_blas_threads()  # the record's numbers must not depend on the machine's cores
        self.clock = clock
        self.journal = journal
        self.listener = listener
        self.resume = resume
        self.repeat = set(repeat)
        self.header = dict(header) if header is not None else None
        self.sheets_used = sheets_used
        self.beside = beside
        old = journal.records
        lines = journal.lines or list(range(1, len(old) + 1))
        self._blocks = {r["key"]: r for r in old if r.get("kind") == "block"}
        replayed = [(r, n) for r, n in zip(old, lines, strict=True)
                    if r.get("kind") in ("step", "sheet")]
        self._old = [r for r, _ in replayed]
        self._old_lines = [n for _, n in replayed]
        self._old_sheets: dict[str, Any] = {}
        if resume == "skip":
            self._old_sheets = {r["name"]: _sheet_value(journal, r, n, sheet_models)
                                for r, n in replayed
                                if r["kind"] == "sheet"}
            self._old = []
        self._pos = 0
        self._saved: list[str] = []  # names of the sheets saved, in order
        self.restored: list[str] = []  # blocks restored from the journal (skip mode)
        self.check_sheets: dict[str, CheckSheet] = {}
        self.sheets: dict[str, Any] = {}
        self._open: list[CheckSheet] = []  # check-sheets being ticked, innermost last

    @property
    def replaying(self) -> bool:
        return self._pos < len(self._old)

    def _emit(self, rec: dict) -> None:
        rec = {**rec, "wall": dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")}
        if self.replaying:
            old = self._old[self._pos]
            if _stable(old) != _stable(rec):
                what = " ".join(str(x) for x in (old.get("kind"), old.get("chart", old.get(
                    "name")), old.get("step", "")) if x != "")
                raise ResumeMismatch(
                    f"{self.journal.path}:{self._old_lines[self._pos]}: the replay differs "
                    f"from the journal's {what}: was the seed, config or code changed?"
                )
            self._pos += 1
        else:
            self.journal.append(rec)
        if self.listener:
            self.listener(rec)

    def meanwhile(self, job: str, **kwargs: Any) -> Callable[[], Any]:
        """The pure function ``job`` (``"module:function"``) of ``kwargs`` as they are now,
        computed beside the run while it goes on (on the second core, issue 17) or, without
        ``beside``, here when the value is first asked for, on the arguments as they were
        (as when the race below is lost: an error in it is met where the value is needed,
        in that step); call the returned callable for its value, which is then
        made here if the second process has not given it yet and is not on it (busy with
        a plot, on a loaded machine: the run does not wait for it). Only a computation
        whose value does not depend on where it runs belongs here (no clock, no drivers,
        no journal)."""
        if self.beside is not None:
            return self.beside.compute(job, kwargs, race=True)
        module, _, function = job.partition(":")
        f = getattr(import_module(module), function)
        sent = pickle.dumps(kwargs)  # the arguments now, as a second process has them
        return cache(lambda: f(**pickle.loads(sent)))

    def note(self, **data: Any) -> None:
        """A free record (run start, settings); journaled unless replaying."""
        if not self.replaying:
            self.journal.append({"kind": "note", **data})

    @contextmanager
    def sheet(self, chart: str, title: str) -> Iterator[CheckSheetRun]:
        cs = CheckSheet(chart=chart, title=title, header=self.header_for(f"check_{chart}"))
        self.check_sheets[chart] = cs
        if self.listener:
            self.listener({"kind": "sheet_start", "chart": chart, "title": title})
        self._open.append(cs)
        try:
            yield CheckSheetRun(self, cs)
        finally:
            self._open.pop()
        self.save_sheet(f"check_{chart}", cs)

    def header_for(self, name: str) -> SheetHeader | None:
        """The heading of the sheet ``name`` (None when the run has no header)."""
        if self.header is None:
            return None
        used = self.sheets_used(name) if self.sheets_used is not None else []
        return SheetHeader.model_validate({**self.header, "sheets_used": used})

    def save_sheet(self, name: str, model: Any) -> None:
        if (self.header is not None and isinstance(model, BaseModel)
                and "header" in type(model).model_fields
                and getattr(model, "header", None) is None):
            setattr(model, "header", self.header_for(name))  # noqa: B010 - any sheet model
        self.sheets[name] = model
        self._saved.append(name)
        self._emit({"kind": "sheet", "name": name, "data": model})

    def block(self, key: str, fn: Callable[[], Any], load: Callable[[Any], T]) -> T:
        """Run a whole chart ``fn`` and journal its result; return ``load`` of that result.

        The result always goes through its journal form (JSON), so a fresh run and a run
        restored from the journal see the same values; the listener gets it as
        ``{"kind": "block", "key", "data"}`` once the chart is run (not when restored). In
        skip mode a block completed in the journal (and matching no ``repeat`` pattern) is
        restored, with the sheets it saved and the steps it ticked on the open check-sheet,
        instead.
        """
        done = self._blocks.get(key)
        open_sheet = self._open[-1] if self._open else None
        if (self.resume == "skip" and done is not None
                and not any(fnmatchcase(key, p) for p in self.repeat)):
            for name in done.get("sheets", []):
                self._restore_sheet(name)
            if open_sheet is not None:
                open_sheet.steps.extend(StepRecord.model_validate(r)
                                        for r in done.get("steps", []))
            self.restored.append(key)
            self.journal.append({"kind": "note", "event": "restored", "block": key})
            return load(done["data"])
        first = len(self._saved)
        first_step = len(open_sheet.steps) if open_sheet is not None else 0
        with self.journal.held():  # its sheets are synced with the block's record
            value = json.loads(dumps({"x": fn()}))["x"]
        if self.resume == "skip" or done is None:
            rec = {"kind": "block", "key": key, "data": value,
                   "sheets": list(dict.fromkeys(self._saved[first:]))}
            if open_sheet is not None:
                rec["steps"] = [r.model_dump(mode="json")
                                for r in open_sheet.steps[first_step:]]
            self.journal.append(rec)
            self._blocks[key] = rec
        if self.listener:  # a chart's data, as soon as it exists (not journaled again)
            self.listener({"kind": "block", "key": key, "data": value})
        return load(value)

    def _restore_sheet(self, name: str) -> None:
        value = self._old_sheets[name]
        self.sheets[name] = value
        if isinstance(value, CheckSheet):
            self.check_sheets[value.chart] = value


class CheckSheetRun:
    def __init__(self, run: Run, sheet: CheckSheet) -> None:
        self.run = run
        self.sheet = sheet

    @contextmanager
    def step(self, number: str, text: str) -> Iterator[StepContext]:
        chart = self.sheet.chart
        token = current_step.set(StepName(chart, number))
        ctx = StepContext()
        try:
            yield ctx
        except ProcedureError:
            raise
        except Exception as e:  # noqa: BLE001 - every failure becomes a named step failure
            if not self.run.replaying:
                self.run.journal.append(
                    {"kind": "failed", "chart": chart, "step": number, "text": text,
                     "t_sim": self.run.clock.now(), "error": str(e)}
                )
            raise ProcedureError(chart, number, text, str(e)) from e
        finally:
            current_step.reset(token)
        t = self.run.clock.now()
        rec = StepRecord(number=number, text=text, done=True, t_sim=t, reading=ctx.reading)
        self.sheet.steps.append(rec)
        self.run._emit(
            {"kind": "step", "chart": chart, "step": number, "text": text, "t_sim": t,
             "reading": ctx.reading}
        )

    def done(self, number: str, text: str, reading: Any = None) -> None:
        """A step with nothing to do but record (a verification, a reading already taken)."""
        with self.step(number, text) as s:
            s.reading = reading
