"""Line-protocol exchange over any pyserial URL (sim://, a pty, /dev/ttyUSB0, socket://...).

One command, one reply line, matched to its command (docs/protocols.md, "Replies and their
commands"):

* input already waiting when a command is sent answers nothing the driver asked: it is
  reported (a log warning and the driver's ``unexpected`` count) and dropped;
* the reply is the first line of the form the command expects, or an ``ERR`` refusal; any
  other line is reported and dropped, and the driver waits on until the command's timeout;
* when nothing at all came within the timeout the reply may still be on its way, so the
  link is out of step: the driver drops its input, and sends its next command after
  ``*CLS`` (which also cancels a waiting ``READ?``/``MEAS?``) and ``*IDN?``, skipping
  everything up to the identity before it takes the reply.

Timeouts, refusals, malformed replies and readings out of range are DriverError subclasses
naming the instrument, the link, the command and the procedure step.
"""

from __future__ import annotations

import logging
import re
from collections import deque
from collections.abc import Callable
from typing import Any

import serial

import station.links  # noqa: F401  (registers the sim:// handler)
from station.clock import Clock
from station.drivers import replies
from station.errors import (
    DriverError,
    InstrumentRefused,
    LinkTimeout,
    MalformedReply,
    ReadingOutOfRange,
    current_step,
)

log = logging.getLogger("station.drivers")

MAX_REPLY = 512  # bytes of the longest reply line taken (the longest real one is ~120)
MAX_LINES = 64  # lines read while waiting for one reply before the link is called babbling
KEEP_REPORTED = 32  # unexpected lines kept on the driver for inspection


class AnyLine:
    """The reply form of a free query: any printable line."""

    name = "a printable ASCII line"

    def matches(self, text: str) -> bool:
        return True

    def parse(self, text: str) -> str:
        return text


class Matching:
    """A reply form given by one regular expression (an identity)."""

    def __init__(self, pattern: re.Pattern[str], name: str) -> None:
        self.pattern, self.name = pattern, name

    def matches(self, text: str) -> bool:
        return self.pattern.fullmatch(text) is not None

    def parse(self, text: str) -> str:
        return text


def show(b: bytes) -> str:
    """Bytes as received, for messages (undecodable bytes as \\xNN)."""
    return b.decode("ascii", errors="backslashreplace")


def printable(body: bytes) -> str | None:
    """The line as text if it is printable ASCII, else None."""
    try:
        text = body.decode("ascii")
    except UnicodeDecodeError:
        return None
    return text if text.isprintable() else None


def strip_eol(raw: bytes) -> bytes:
    """A line without its ``\\n`` and one ``\\r`` before it."""
    body = raw[:-1] if raw.endswith(b"\n") else raw
    return body[:-1] if body.endswith(b"\r") else body


class SerialDriver:
    """One serial instrument's link: exchanges matched to their commands, replies parsed
    against their forms (station/drivers/replies.py)."""

    model: tuple[str, str] | None = None  # maker and model in *IDN? (None: any instrument)

    @property
    def identity(self) -> re.Pattern[str]:
        """The ``*IDN?`` reply this driver's instrument gives: its maker and model, any
        unit and version."""
        return replies.ANY_IDENTITY if self.model is None else replies.identity(*self.model)

    def __init__(self, name: str, url: str, clock: Clock | None = None,
                 timeout: float = 5.0) -> None:
        """The one constructor convention of every driver: the instrument's name in the
        rack, its link (a pyserial URL), the station clock (None: a bare link whose
        timeouts are taken as given, as ``station check`` and protocol tests use it) and
        the reply timeout in the clock's seconds."""
        self.name = name
        self.url = url
        self.timeout = timeout
        self.link_seconds: Callable[[float], float] = float  # station -> link timeout
        self.link_clock: Clock | None = None  # deadlines of multi-line waits, once bound
        self.ident: str | None = None  # the identity as this instrument gave it
        self.last_reply = ""  # the last reply taken by ask()
        self.unexpected = 0  # lines received that answered nothing asked (all reported)
        self.unexpected_lines: deque[str] = deque(maxlen=KEEP_REPORTED)
        self.out_of_step = False  # resynchronise (*CLS, *IDN?) before the next reply
        self._resync = False  # skipping input up to the identity, in this exchange
        try:
            self.port = serial.serial_for_url(url, timeout=timeout, baudrate=115200)
        except (serial.SerialException, OSError, ValueError) as e:
            raise DriverError(name, url, f"cannot open link: {e}") from None
        self.clock = clock
        if clock is not None:
            self.bind_clock(clock)

    def needs_clock(self) -> Clock:
        """The station clock, for a driver method that waits on it (a positioner's hold)."""
        if self.clock is None:
            raise DriverError(self.name, self.url, "opened without the station clock: "
                              "cannot wait on it")
        return self.clock

    def bind_clock(self, clock: Clock) -> None:
        """Give the link its timeouts in wall seconds when the station runs on a real-time
        clock (a served rack may run faster than the wall); virtual links keep them."""
        self.link_clock = clock
        self.link_seconds = clock.link_seconds
        self.port.timeout = self.link_seconds(self.timeout)

    def close(self) -> None:
        self.port.close()

    # ----- exchanges -----
    def query(self, cmd: str, timeout: float | None = None) -> str:
        """Send one command line; return its reply, any printable line (ERR raises)."""
        return self._exchange(cmd, AnyLine(), timeout)

    def ask(self, cmd: str, form: Any, timeout: float | None = None) -> Any:
        """Send ``cmd``; the values of its reply of ``form`` (a replies.Form, OneOf, ...)."""
        text = self.last_reply = self._exchange(cmd, form, timeout)
        try:
            return form.parse(text)
        except replies.OutOfRange as e:
            raise ReadingOutOfRange(self.name, self.url,
                                    f"reply {text!r} to '{cmd}' refused: {e}", cmd, text) from None
        except replies.Malformed as e:  # a form whose matches() and parse() disagree
            raise MalformedReply(self.name, self.url, f"reply to '{cmd}': {e}", cmd,
                                 (text,)) from None

    def refuse(self, cmd: str, why: str) -> ReadingOutOfRange:
        """The error for the last reply (well-formed) that a driver's own check refuses."""
        return ReadingOutOfRange(self.name, self.url, f"reply {self.last_reply!r} to '{cmd}' "
                                 f"refused: {why}", cmd, self.last_reply)

    def whole(self, x: Any, what: str, lo: int, hi: int) -> int:
        """A whole-number argument in [lo, hi] for a command, or DriverError (never sent)."""
        try:
            ok = float(x) == int(x) and lo <= int(x) <= hi
        except (TypeError, ValueError, OverflowError):
            ok = False
        if not ok:
            raise DriverError(self.name, self.url,
                              f"{what} must be a whole number in [{lo}, {hi}], got {x!r}")
        return int(x)

    def command(self, cmd: str, timeout: float | None = None) -> None:
        """Send a command whose reply is ``OK``."""
        self._exchange(cmd, replies.OK, timeout)

    def identify(self) -> str:
        """``*IDN?``: the instrument's identity, which must be this driver's model."""
        maker, model = self.model or ("<maker>", "<model>")
        self.ident = self._exchange(
            "*IDN?", Matching(self.identity, f"'{maker},{model},<unit>,<version>'"), None)
        return self.ident

    def clear(self) -> None:
        """Device clear: drop pending replies (reported) and the error queue.

        Out of step, resynchronise first with an ``*IDN?``: a ``*CLS`` pipelined behind the
        resync's ``*IDN?`` would empty the output queue of the identity it waits for."""
        if self.out_of_step:
            self.identify()
        self.command("*CLS")

    def _exchange(self, cmd: str, form: Any, timeout: float | None) -> str:
        if not cmd.strip() or not cmd.isascii() or not cmd.isprintable():
            raise DriverError(self.name, self.url,
                              f"command {cmd!r} is not one line of printable ASCII", cmd)
        waited = self.timeout if timeout is None else float(timeout)
        port = self.port
        try:
            self._drain(cmd)
            prefix = b""
            if self.out_of_step:  # a reply to an earlier command may still come
                prefix, self._resync = b"*CLS\n*IDN?\n", True
            port.write(prefix + (cmd + "\n").encode("ascii"))
            return self._reply(cmd, form, waited)
        except (serial.SerialException, OSError) as e:
            raise DriverError(self.name, self.url, f"link failed during '{cmd}': {e}",
                              cmd) from None
        finally:
            self._resync = False
            self._set_timeout(self.timeout)

    def _reply(self, cmd: str, form: Any, waited: float) -> str:
        """Lines until the reply of ``form`` (or an ERR) to ``cmd``, within ``waited``."""
        clock = self.link_clock
        t_end = None if clock is None else clock.now() + waited
        dropped: list[str] = []  # lines that were not the reply, as received
        overlong = False
        for _ in range(MAX_LINES):
            left = waited if t_end is None or clock is None else max(0.0, t_end - clock.now())
            self.port.timeout = self.link_seconds(left)  # a failing link raises here: reported
            raw = self.port.read_until(b"\n", MAX_REPLY + 2)
            if not raw.endswith(b"\n"):
                if len(raw) < MAX_REPLY + 2:
                    self._timed_out(cmd, form, waited, raw, dropped)
                if not overlong:
                    overlong = True
                    dropped.append(show(raw[:40]) + "... (over-long line)")
                    self._report(dropped[-1], f"while waiting for the reply to '{cmd}'")
                continue
            if overlong:  # the end of the over-long line, already reported
                overlong = False
                continue
            body = strip_eol(raw)
            if self._background(body):
                continue
            text = printable(body)
            if self._resync:
                if text is not None and self._marks_sync(text):
                    self._resync = self.out_of_step = False
                else:
                    self._report(show(body), f"stale, skipped before the reply to '{cmd}'")
                continue
            if text is not None:
                m = replies.ERR.fullmatch(text)
                if m:
                    raise InstrumentRefused(self.name, self.url, int(m[1]), m[2] or "", cmd)
                if form.matches(text):
                    return text
            dropped.append(show(body))
            self._report(dropped[-1], f"not {form.name}: dropped while waiting for the "
                         f"reply to '{cmd}'")
        self.lose_step()
        raise MalformedReply(self.name, self.url, f"no reply to '{cmd}' among {MAX_LINES} "
                             f"lines (link babbling); first: {dropped[:1]}", cmd,
                             tuple(dropped))

    def _timed_out(self, cmd: str, form: Any, waited: float, partial: bytes,
                   dropped: list[str]) -> None:
        """Raise the error for a wait that ended without the reply; the link is out of step
        if the reply may still come (nothing of it arrived, or not even the identity)."""
        resyncing = self._resync
        if (not partial and not dropped) or resyncing:
            self.lose_step()
        got = f" (partial reply {partial[:40]!r})" if partial else ""
        if resyncing:
            got += " (resynchronising after an earlier timeout: no identity came)"
        if dropped and not resyncing:
            more = f" and {len(dropped) - 1} more line(s)" if len(dropped) > 1 else ""
            raise MalformedReply(
                self.name, self.url,
                f"unexpected reply {dropped[0]!r}{more} to '{cmd}' (expected {form.name}); "
                f"no reply of that form within {waited:g} s{got}", cmd, tuple(dropped))
        raise LinkTimeout(self.name, self.url, f"no reply to '{cmd}' within {waited:g} s{got}",
                          cmd)

    def _set_timeout(self, seconds: float) -> None:
        """Put the link's own timeout back; a link that has failed is left as it is (its
        failure is what the exchange reports, or the next one will)."""
        try:
            self.port.timeout = self.link_seconds(seconds)
        except (serial.SerialException, OSError):
            pass

    def lose_step(self) -> None:
        """Drop the input; the next exchange resynchronises first (a reply to an earlier
        command may still come)."""
        self.port.reset_input_buffer()
        self.out_of_step = True

    def _marks_sync(self, text: str) -> bool:
        """The end of stale output: this instrument's identity (by its model's pattern, so a
        damaged earlier *IDN? reply cannot make the marker wrong)."""
        return self.identity.fullmatch(text) is not None

    def _drain(self, cmd: str) -> None:
        """Report and drop the input waiting before ``cmd`` is sent (a stray line, the
        tail of a damaged reply, a late reply)."""
        n = self.port.in_waiting
        if not n:
            return
        lines = self.port.read(n).split(b"\n")
        for i, raw in enumerate(lines):
            last = i == len(lines) - 1
            if last and not raw:
                break
            body = strip_eol(raw)
            if self._background(body):
                continue
            self._report(show(body) + (" (no end of line)" if last else ""),
                         f"{'stale' if self.out_of_step else 'unexpected'}: waiting before "
                         f"'{cmd}'")

    def _background(self, body: bytes) -> bool:
        """Lines an instrument sends unasked that are no reply (the ESG processor's data
        lines); skipped silently while waiting for a reply."""
        return False

    def _report(self, line: str, why: str) -> None:
        self.unexpected += 1
        self.unexpected_lines.append(line)
        step = current_step.get()
        log.warning("%s (%s)%s: line %r %s", self.name, self.url,
                    f" during {step}" if step else "", line, why)
