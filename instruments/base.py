"""Common machinery: byte-stream instruments with line protocols, answering as SCPI devices do.

Every instrument declares its command words with their synopsis (:meth:`ByteInstrument.define`);
the synopsis fixes how many arguments a word takes, so a missing or extra argument is refused
before any action runs. Arguments are read with strict grammars (:func:`as_int`, :func:`as_float`,
:func:`as_choice`), never with Python's lenient ``int``/``float`` (underscores, ``+``, unicode
digits, surrounding blanks are not numbers on this wire).

Replies leave in command order after the instrument's latency. A query may answer later
(a counter's READ? waits for a reading): later replies queue behind it, as on a real SCPI
device. The output queue holds at most :data:`MAX_REPLIES` replies; a line arriving while it
is full is not executed and ``350 queue overflow`` goes on the error queue. ``*CLS`` (and
``DCL``) empties the error queue and the output queue. A host's bad argument is ``ERR 11``/
``ERR 12``; a fault of the simulation itself is ``ERR 200 internal: ...`` naming what failed.
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import simpy

from sim.timebase import ticks

if TYPE_CHECKING:
    from instruments.output_faults import ReplyFault

MAX_LINE = 256  # bytes of one command line
MAX_REPLIES = 256  # replies waiting to leave: the output queue's size
MAX_ERRORS = 32  # entries of the error queue (the oldest is dropped when full)
CLEARS = ("*CLS", "DCL")  # executed even with the output queue full: they empty it

# error codes shared by every serial instrument (docs/protocols.md)
UNKNOWN, USAGE, RANGE, GARBLED = 10, 11, 12, 100
OVERFLOW = 350  # as SCPI's -350 "queue overflow"
INTERNAL = 200  # a fault of the simulated instrument, never of the host's command

_INT = re.compile(r"-?[0-9]+")
_REAL = re.compile(r"-?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?")
_SYNOPSIS_WORD = re.compile(r"\[[^\]]*\]|<[^>]*>|\S+")  # "[<axis>]", "<pulses per rev>", "Z|XY"
_NON_FINITE = re.compile(r"-?(?:nan|inf|infinity)", re.IGNORECASE)


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


Reply = str | Deferred | None
Action = Callable[[list[str]], Reply]


@dataclass(frozen=True)
class Verb:
    """One command word: its synopsis, the argument counts the synopsis allows, its action."""

    usage: str
    action: Action
    min_args: int
    max_args: int


def verb(usage: str, action: Action) -> Verb:
    """A :class:`Verb` from a synopsis such as ``POS <axis> <deg>`` or ``STOP [<axis>]``:
    each word after the command is one argument, a word in brackets an optional one."""
    words = _SYNOPSIS_WORD.findall(usage.partition(" ")[2])
    optional = sum(w.startswith("[") for w in words)
    return Verb(usage, action, len(words) - optional, len(words))


def printable(text: str, limit: int = 160) -> str:
    """``text`` as one printable-ASCII line of at most ``limit`` characters."""
    return "".join(c if " " <= c <= "~" else "?" for c in text)[:limit]


class ByteInstrument:
    """Base of serial instruments: bytes in via :meth:`receive`, bytes out in :attr:`output`."""

    ident = "ISU-LAB,GENERIC,0,1.0"

    def __init__(self, name: str, env: simpy.Environment, latency_s: float) -> None:
        self.name = name
        self.env = env
        self.latency = ticks(latency_s)
        self.output = bytearray()
        self.listeners: list[Callable[[bytes], None]] = []
        self.verbs: dict[str, Verb] = {}
        self.errors: deque[str] = deque(maxlen=MAX_ERRORS)
        self.internal_faults: list[str] = []  # every ERR 200 raised, for tests and benches
        self.silent = False  # fault injection: stops answering
        self.reply_fault: ReplyFault | None = None  # fault injection: delayed, lost, garbled bytes
        self.replies_queued = 0  # replies accepted into the output queue so far
        self.replies_done = 0  # of those, replies sent or dropped by a clear
        self._done_event = env.event()
        self._inbuf = bytearray()
        self._replies: deque[str | Deferred] = deque()
        self._generation = 0  # bumped by every clear: a reply in flight from before is dropped
        self._overflowing = False  # one overflow error per episode of a full queue
        self._wake = env.event()
        self._discarding = False  # skipping the rest of an over-long line up to its newline
        self.define("*IDN?", lambda _: self.ident)
        self.define("SYST:ERR?", self._next_error)
        for word in CLEARS:
            self.define(word, self._clear_status)
        env.process(self._reply_loop())

    # --- declaring the protocol ---
    def define(self, usage: str, action: Action) -> None:
        """Add (or replace) the command word of ``usage``: ``define("POS <axis> <deg>", f)``."""
        v = verb(usage, action)
        self.verbs[usage.split()[0].upper()] = v

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
                        self._queue(self._error(GARBLED, "garbled input: line too long"))
                return
            raw = bytes(self._inbuf[:i]).rstrip(b"\r")
            del self._inbuf[: i + 1]
            if self._discarding:  # the end of an over-long line, already refused
                self._discarding = False
                continue
            if i > MAX_LINE:  # an over-long line that arrived in one piece
                self._queue(self._error(GARBLED, "garbled input: line too long"))
                continue
            self._handle_raw(raw)

    def _handle_raw(self, raw: bytes) -> None:
        if not raw.strip(b" "):  # a blank line: no reply
            return
        if self.output_full():
            head = raw.strip(b" ").split(b" ")[0].decode("latin-1")
            if head.upper() not in CLEARS:
                self._overflow(head)
                return
        reply = self.reply_to(raw)
        if reply is not None:
            self._queue(reply)

    def reply_to(self, raw: bytes) -> Reply:
        """Run one command line (without its newline) and return its reply; never raises.

        The reply is text, a :class:`Deferred` for a query that answers later, or None for
        a blank line. Refusals are ``ERR <code> <text>`` texts, also put on the error queue.
        """
        if not raw.strip(b" "):
            return None
        try:
            line = raw.decode("ascii")
            if not line.isprintable():
                raise UnicodeDecodeError("ascii", raw, 0, len(raw), "control character")
        except UnicodeDecodeError:
            return self._error(GARBLED, "garbled input: not printable ASCII")
        words = line.split()
        head = words[0].upper()
        try:
            return self.execute(head, words[1:])
        except InstrumentError as e:
            return self._error(e.code, e.text)
        except Exception as e:  # noqa: BLE001 - a fault of the simulation, reported as such
            return self.internal_error(head, e)

    def execute(self, head: str, args: list[str]) -> Reply:
        """Run command word ``head`` (upper case) with ``args``: arity first, then its action."""
        v = self.verbs.get(head)
        if v is None:
            raise InstrumentError(UNKNOWN, f"unknown command '{head[:32]}'")
        if not v.min_args <= len(args) <= v.max_args:
            raise InstrumentError(USAGE, f"usage: {v.usage}")
        return v.action(args)

    # --- errors ---
    def _error(self, code: int, text: str) -> str:
        msg = f"ERR {code} {text}"
        self.errors.append(msg)
        return msg

    def log_error(self, code: int, text: str) -> None:
        """An error the instrument found on its own (no reply): on the error queue only."""
        self._error(code, text)

    def internal_error(self, what: str, exc: BaseException) -> str:
        """The reply for a fault of the simulated instrument itself, naming what failed."""
        text = printable(f"internal: {what} failed: {type(exc).__name__}: {exc}")
        self.internal_faults.append(text)
        return self._error(INTERNAL, text)

    def _next_error(self, _: list[str]) -> str:
        # "<code> <text>" (without the ERR prefix: this is an answer, not a refusal)
        return self.errors.popleft()[4:] if self.errors else "0 no error"

    # --- the output queue ---
    def pending(self) -> tuple[str | Deferred, ...]:
        """The replies waiting to leave, oldest first (for tests and benches)."""
        return tuple(self._replies)

    def output_full(self) -> bool:
        return len(self._replies) >= MAX_REPLIES

    def _overflow(self, head: str) -> None:
        if not self._overflowing:
            self._overflowing = True
            self._error(OVERFLOW, f"queue overflow: {MAX_REPLIES} replies waiting, "
                                  f"'{printable(head, 20)}' and later lines not executed")

    def _queue(self, reply: str | Deferred) -> bool:
        """Put a reply on the output queue; False (and an overflow error) if it is full."""
        if self.output_full():
            if isinstance(reply, Deferred):
                reply.cancel()
            self._overflow("reply")
            return False
        self._replies.append(reply)
        self.replies_queued += 1
        if not self._wake.triggered:
            self._wake.succeed()
        return True

    def _done(self, n: int) -> None:
        if n:
            self.replies_done += n
            if self._done_event.callbacks:  # a process waits on it (processes yield at once)
                ev, self._done_event = self._done_event, self.env.event()
                ev.succeed()  # unwaited, it would only cost the simulation a step

    def clear_output(self) -> None:
        """Drop every reply not yet sent (device clear); a waiting query is cancelled."""
        for r in self._replies:
            if isinstance(r, Deferred):
                r.cancel()
        n = len(self._replies)
        self._replies.clear()
        self._generation += 1
        self._overflowing = False
        self._done(n)

    def on_clear(self) -> None:
        """What ``*CLS`` resets besides the queues (an instrument's latched fault)."""

    def _clear_status(self, _: list[str]) -> str:
        self.errors.clear()
        self.clear_output()
        self.on_clear()
        return "OK"

    def _reply_loop(self) -> Generator[simpy.Event, Any, None]:
        while True:
            if not self._replies:
                self._wake = self.env.event()
                yield self._wake
                continue
            item = self._replies[0]
            gen = self._generation
            text: str
            if isinstance(item, Deferred):
                if not item.cancelled:
                    yield item.event | item.cancel_event
                if gen != self._generation:  # cleared meanwhile: the item is gone already
                    continue
                self._replies.popleft()
                if item.cancelled:
                    self._done(1)
                    continue
                text = str(item.event.value)
            else:
                self._replies.popleft()
                text = item
            if len(self._replies) < MAX_REPLIES // 2:  # room again: a new overflow is news
                self._overflowing = False
            f = self.reply_fault
            delay = self.latency if f is None else self.latency + f.latency
            if delay:
                yield self.env.timeout(delay)
                if gen != self._generation:  # a clear while this reply was on its way out
                    self._done(1)
                    continue
            self._emit((text + "\n").encode("ascii"))
            self._done(1)

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


# --------------------------------------------------------------------------- arguments


def as_int(x: str, what: str, lo: int, hi: int) -> int:
    """An integer argument: optional ``-`` and ASCII digits only, within [lo, hi]."""
    if not _INT.fullmatch(x):
        raise InstrumentError(USAGE, f"{what} must be an integer, got '{x[:20]}'")
    v = int(x)
    if not lo <= v <= hi:
        raise InstrumentError(RANGE, f"{what} {printable(str(v), 24)} outside [{lo}, {hi}]")
    return v


def as_float(x: str, what: str) -> float:
    """A real argument: optional ``-``, digits with an optional point, optional exponent."""
    if _NON_FINITE.fullmatch(x):
        raise InstrumentError(USAGE, f"{what} must be finite")
    if not _REAL.fullmatch(x):
        raise InstrumentError(USAGE, f"{what} must be a number, got '{x[:20]}'")
    v = float(x)
    if v in (float("inf"), float("-inf")):
        raise InstrumentError(USAGE, f"{what} must be finite")
    return v


def as_real_in(x: str, what: str, lo: float, hi: float, hi_open: bool = False) -> float:
    """A real argument within [lo, hi] (or [lo, hi) with ``hi_open``)."""
    v = as_float(x, what)
    if v < lo or v > hi or (hi_open and v >= hi):
        right = ")" if hi_open else "]"
        raise InstrumentError(RANGE, f"{what} {v:g} outside [{lo:g}, {hi:g}{right}")
    return v


def as_choice(x: str, what: str, options: tuple[str, ...], code: int = USAGE) -> str:
    """One of ``options`` (case-insensitive), upper-cased."""
    w = x.upper()
    if w not in options:
        raise InstrumentError(code, f"{what} must be {' or '.join(options)}, got '{x[:10]}'")
    return w
