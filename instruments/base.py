"""Common machinery: byte-stream instruments with line protocols, and CAN-frame instruments.

Replies leave in command order after the instrument's latency. A query may answer later
(a counter's READ? waits for a reading): later replies queue behind it, as on a real
SCPI device. Garbled input (non-ASCII bytes, over-long lines) gets an error reply.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING

import simpy

from sim.timebase import ticks

if TYPE_CHECKING:
    from instruments.faults import ReplyFault

MAX_LINE = 256


class InstrumentError(Exception):
    """A command the instrument refuses; becomes ``ERR <code> <text>`` on the wire."""

    def __init__(self, code: int, text: str) -> None:
        super().__init__(text)
        self.code = code
        self.text = text


class Deferred:
    """A reply that will exist later (e.g. the next counter reading)."""

    def __init__(self, env: simpy.Environment) -> None:
        self.event = env.event()
        self.cancel_event = env.event()
        self.cancelled = False

    def resolve(self, text: str) -> None:
        if not self.event.triggered and not self.cancelled:
            self.event.succeed(text)

    def cancel(self) -> None:
        self.cancelled = True
        if not self.cancel_event.triggered:
            self.cancel_event.succeed()


class ByteInstrument:
    """Base of serial instruments: bytes in via :meth:`receive`, bytes out in :attr:`output`."""

    ident = "ISU-LAB,GENERIC,0,1.0"

    def __init__(self, name: str, env: simpy.Environment, latency_s: float) -> None:
        self.name = name
        self.env = env
        self.latency = ticks(latency_s)
        self.output = bytearray()
        self.listeners: list[Callable[[bytes], None]] = []
        self._inbuf = bytearray()
        self._replies: deque[str | Deferred] = deque()
        self._wake = env.event()
        self.errors: deque[str] = deque(maxlen=32)
        self.silent = False  # fault injection: stops answering
        self.reply_fault: ReplyFault | None = None  # fault injection: delayed, lost, garbled bytes
        self._discarding = False  # skipping the rest of an over-long line up to its newline
        env.process(self._reply_loop())

    # --- host side ---
    def receive(self, data: bytes) -> None:
        """Bytes from the host, at the current simulated time."""
        self._inbuf.extend(data)
        while True:
            i = self._inbuf.find(b"\n")
            if i < 0:
                if len(self._inbuf) > MAX_LINE:
                    self._inbuf.clear()
                    if not self._discarding:  # one error reply per over-long line
                        self._discarding = True
                        self._queue(self._error(100, "garbled input: line too long"))
                return
            raw = bytes(self._inbuf[:i]).rstrip(b"\r")
            del self._inbuf[: i + 1]
            if self._discarding:  # the end of an over-long line, already refused
                self._discarding = False
                continue
            if i > MAX_LINE:  # an over-long line that arrived in one piece
                self._queue(self._error(100, "garbled input: line too long"))
                continue
            self._handle_raw(raw)

    def _handle_raw(self, raw: bytes) -> None:
        if not raw.strip():
            return
        try:
            line = raw.decode("ascii")
            if not line.isprintable():
                raise UnicodeDecodeError("ascii", raw, 0, len(raw), "control character")
        except UnicodeDecodeError:
            self._queue(self._error(100, "garbled input: not printable ASCII"))
            return
        try:
            reply = self.execute(line.strip())
        except InstrumentError as e:
            reply = self._error(e.code, e.text)
        except (ValueError, IndexError):
            reply = self._error(11, f"bad argument in '{line.strip()[:40]}'")
        if reply is not None:
            self._queue(reply)

    def _error(self, code: int, text: str) -> str:
        msg = f"ERR {code} {text}"
        self.errors.append(msg)
        return msg

    def _queue(self, reply: str | Deferred) -> None:
        self._replies.append(reply)
        if not self._wake.triggered:
            self._wake.succeed()

    def cancel_pending(self) -> None:
        """Drop replies still waiting (device clear)."""
        for r in self._replies:
            if isinstance(r, Deferred):
                r.cancel()

    def _reply_loop(self):
        while True:
            if not self._replies:
                self._wake = self.env.event()
                yield self._wake
                continue
            item = self._replies[0]
            if isinstance(item, Deferred):
                if not item.cancelled:
                    yield item.event | item.cancel_event
                self._replies.popleft()
                if item.cancelled:
                    continue
                text = item.event.value
            else:
                text = self._replies.popleft()
            f = self.reply_fault
            delay = self.latency if f is None else self.latency + f.latency
            if delay:
                yield self.env.timeout(delay)
            self._emit((text + "\n").encode("ascii"))

    def _emit(self, data: bytes) -> None:
        if self.silent:
            return
        if self.reply_fault is not None:
            data = self.reply_fault.garble(data)
            if not data:
                return
        self.output.extend(data)
        for cb in self.listeners:
            cb(data)

    # --- protocol ---
    def execute(self, line: str) -> str | Deferred | None:
        """Run one command line; return the reply text, a Deferred, or None."""
        head, _, rest = line.partition(" ")
        cmd = head.upper()
        args = rest.split()
        if cmd == "*IDN?":
            return self.ident
        if cmd == "SYST:ERR?":
            # "<code> <text>" (without the ERR prefix: this is an answer, not a refusal)
            return self.errors.popleft()[4:] if self.errors else "0 no error"
        if cmd in ("*CLS", "DCL"):
            self.errors.clear()
            self.cancel_pending()
            return "OK"
        return self.command(cmd, args)

    def command(self, cmd: str, args: list[str]) -> str | Deferred | None:
        raise InstrumentError(10, f"unknown command '{cmd}'")


def need(args: list[str], n: int, usage: str) -> None:
    if len(args) != n:
        raise InstrumentError(11, f"usage: {usage}")


def as_float(x: str, what: str) -> float:
    try:
        v = float(x)
    except ValueError:
        raise InstrumentError(11, f"{what} must be a number, got '{x[:20]}'") from None
    if v != v or v in (float("inf"), float("-inf")):
        raise InstrumentError(11, f"{what} must be finite")
    return v


def as_int(x: str, what: str, lo: int, hi: int) -> int:
    try:
        v = int(x)
    except ValueError:
        raise InstrumentError(11, f"{what} must be an integer, got '{x[:20]}'") from None
    if not lo <= v <= hi:
        raise InstrumentError(12, f"{what} {v} outside [{lo}, {hi}]")
    return v
