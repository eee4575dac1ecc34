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
