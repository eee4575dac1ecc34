"""Running a procedure as the laboratory does: check-sheets ticked step by step, journaled.

Every completed step is one journal record (chart, step number, text, simulated time,
reading). A failing step stops its procedure with ``ProcedureError`` naming the chart and
step; everything recorded before it stays in the journal.

Resume: a run opened on an existing journal re-executes the procedures from the start and
checks each step it repeats against the journal (in virtual time this replay is exact and
takes seconds), then goes on appending. A mismatch means the seed, the config or the code
changed, and is refused.
"""

from __future__ import annotations

import datetime as dt
import json
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from procedures.journal import Journal, dumps
from procedures.sheets import CheckSheet, StepRecord
from station.clock import Clock
from station.errors import current_step

VOLATILE = ("wall",)


class ProcedureError(Exception):
    """A step that could not be completed; the message names the chart and the step."""

    def __init__(self, chart: str, step: str, text: str, cause: str) -> None:
        self.chart, self.step, self.cause = chart, step, cause
        super().__init__(f"Chart {chart}, step {step} ({text}): {cause}")


class ResumeMismatch(Exception):
    """The replayed run does not reproduce the journal it resumes."""


def _stable(rec: dict) -> dict:
    return {k: v for k, v in json.loads(dumps(rec)).items() if k not in VOLATILE}


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
    ) -> None:
        self.clock = clock
        self.journal = journal
        self.listener = listener
        self._old = [r for r in journal.records if r.get("kind") in ("step", "sheet")]
        self._pos = 0
        self.check_sheets: dict[str, CheckSheet] = {}
        self.sheets: dict[str, Any] = {}

    @property
    def replaying(self) -> bool:
        return self._pos < len(self._old)

    def _emit(self, rec: dict) -> None:
        rec = {**rec, "wall": dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")}
        if self.replaying:
            old = self._old[self._pos]
            if _stable(old) != _stable(rec):
                raise ResumeMismatch(
                    f"journal record {self._pos + 1} differs from the replay "
                    f"({old.get('kind')} {old.get('chart', old.get('name'))} "
                    f"{old.get('step', '')}): was the seed, config or code changed?"
                )
            self._pos += 1
        else:
            self.journal.append(rec)
        if self.listener:
            self.listener(rec)

    def note(self, **data: Any) -> None:
        """A free record (run start, settings); journaled unless replaying."""
        if not self.replaying:
            self.journal.append({"kind": "note", **data})

    @contextmanager
    def sheet(self, chart: str, title: str) -> Iterator[CheckSheetRun]:
        cs = CheckSheet(chart=chart, title=title)
        self.check_sheets[chart] = cs
        if self.listener:
            self.listener({"kind": "sheet_start", "chart": chart, "title": title})
        yield CheckSheetRun(self, cs)
        self.save_sheet(f"check_{chart}", cs)

    def save_sheet(self, name: str, model: Any) -> None:
        self.sheets[name] = model
        self._emit({"kind": "sheet", "name": name, "data": model})


class CheckSheetRun:
    def __init__(self, run: Run, sheet: CheckSheet) -> None:
        self.run = run
        self.sheet = sheet

    @contextmanager
    def step(self, number: str, text: str) -> Iterator[StepContext]:
        chart = self.sheet.chart
        token = current_step.set(f"Chart {chart} step {number}")
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
