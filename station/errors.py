"""Errors the station reports, each naming the instrument, its link and the procedure step."""

from __future__ import annotations

import contextvars

current_step: contextvars.ContextVar[str | None] = contextvars.ContextVar(
    "current_step", default=None
)


class StationError(Exception):
    """Base of every error the station reports to the operator."""


class DriverError(StationError):
    """A driver could not complete an exchange with its instrument."""

    def __init__(self, instrument: str, link: str, message: str) -> None:
        self.instrument = instrument
        self.link = link
        self.step = current_step.get()
        self.detail = message
        where = f" during {self.step}" if self.step else ""
        super().__init__(f"{instrument} ({link}){where}: {message}")


class LinkTimeout(DriverError):
    """No (complete) reply within the timeout."""


class InstrumentRefused(DriverError):
    """The instrument answered with an error reply (ERR code text)."""

    def __init__(self, instrument: str, link: str, code: int, text: str) -> None:
        self.code = code
        self.text = text
        super().__init__(instrument, link, f"instrument error {code}: {text}")


class Deadlock(StationError):
    """A virtual-time wait with nothing scheduled that could ever satisfy it."""
