"""Errors the station reports to the operator, each naming what failed and where.

One root, :class:`OperatorError`, with a class attribute ``exit_code`` and two families:

* :class:`UseError` (exit 2): the command was not run as asked and nothing was measured (a
  bad configuration or argument, a run directory that may not be used, a journal that cannot
  be resumed, no or the wrong served rack);
* :class:`StopError` (exit 1): a procedure stopped (a failed check, :class:`CheckFailed`; a
  driver's exchange that failed, :class:`DriverError`; a step that could not be completed).

The command line turns any of them into one line on stderr and its exit code, in one place.
"""

from __future__ import annotations

import contextvars
from typing import ClassVar


class StepName(str):
    """``Chart <chart> step <step>`` as messages print it, with the chart and the step kept
    apart (a failed check raised inside the step takes both from it)."""

    chart: str
    step: str

    def __new__(cls, chart: str, step: str) -> StepName:
        name = super().__new__(cls, f"Chart {chart} step {step}")
        name.chart, name.step = chart, step
        return name


# The check-sheet step being run (set by the procedures' runner; None outside any step).
current_step: contextvars.ContextVar[str | None] = contextvars.ContextVar(
    "current_step", default=None
)


class OperatorError(Exception):
    """Root of every error the operator is told about: one line and one exit code."""

    exit_code: ClassVar[int] = 1


class UseError(OperatorError):
    """The command was not run as asked (configuration, argument, run directory, journal,
    served rack): nothing was measured."""

    exit_code: ClassVar[int] = 2


class BadArgument(UseError):
    """A command-line argument that cannot be used as given."""


class VerdictFailed(OperatorError):
    """A run that completed, its record whole, with a result row outside its acceptance
    limit (exit 3): the message lists the failed rows."""

    exit_code: ClassVar[int] = 3

    def __init__(self, failed: list[str]) -> None:
        self.failed = list(failed)
        super().__init__(f"FAIL ({len(self.failed)} rows: {', '.join(self.failed)})")


class StopError(OperatorError):
    """A procedure stopped: what it measured so far stays in its journal."""

    exit_code: ClassVar[int] = 1


class CheckFailed(StopError):
    """A check the procedure makes did not pass (a reading out of tolerance, a search that
    did not converge, a precondition not met). ``chart`` and ``step`` name the check-sheet
    step it was raised in (None outside a step); the message is the caller's, unchanged."""

    def __init__(self, message: str, chart: str | None = None,
                 step: str | None = None) -> None:
        at = current_step.get()
        self.chart = chart if chart is not None else getattr(at, "chart", None)
        self.step = step if step is not None else getattr(at, "step", None)
        super().__init__(message)


class StationError(StopError):
    """Base of the errors the rack reports while a procedure runs (a driver's exchange, a
    virtual-time wait that can never end)."""
class DriverError(StationError):
    """A driver could not complete an exchange with its instrument."""

    def __init__(self, instrument: str, link: str, message: str,
                 command: str | None = None) -> None:
        self.instrument = instrument
        self.link = link
        self.command = command  # the command whose exchange failed, when there was one
        self.step = current_step.get()
        self.detail = message
        where = f" during {self.step}" if self.step else ""
        super().__init__(f"{instrument} ({link}){where}: {message}")


class LinkTimeout(DriverError):
    """No (complete) reply within the timeout."""


class MalformedReply(DriverError):
    """The instrument answered, but with no line of the form the protocol defines for the
    command (every line that came is named in the message)."""

    def __init__(self, instrument: str, link: str, message: str, command: str,
                 lines: tuple[str, ...] = ()) -> None:
        self.lines = lines
        super().__init__(instrument, link, message, command)


class ReadingOutOfRange(DriverError):
    """A well-formed reading outside what the instrument can physically report."""

    def __init__(self, instrument: str, link: str, message: str, command: str,
                 reply: str) -> None:
        self.reply = reply
        super().__init__(instrument, link, message, command)


class InstrumentRefused(DriverError):
    """The instrument answered with an error reply (ERR code text)."""

    def __init__(self, instrument: str, link: str, code: int, text: str,
                 command: str | None = None) -> None:
        self.code = code
        self.text = text
        said = f" on '{command}'" if command else ""
        super().__init__(instrument, link, f"instrument error {code}{said}: {text}", command)


class Deadlock(StationError):
    """A virtual-time wait with nothing scheduled that could ever satisfy it."""
