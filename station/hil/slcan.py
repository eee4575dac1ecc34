"""An slcan (Lawicel ASCII) CAN adapter on a pty, for python-can's ``interface="slcan"``.

Commands end with CR; the adapter answers CR for OK and BEL for an error. python-can opens
with ``C``, ``S<n>``, an empty line, ``O`` and ``O`` again (the second ``O`` is accepted,
not refused, since python-can always sends it). Frames: ``tIIIL<data hex>`` (standard data
frames only: the IEU bus carries nothing else); a sent frame is acknowledged ``z`` CR as by
a Lawicel adapter. Frames reach the host only while the channel is open; ``C`` also drops
frames still queued for the host (pyserial's flush on open clears the pty itself). A line
longer than ``MAX_LINE`` is refused whole with one BEL: nothing up to its CR is executed.

:class:`SlcanLines` splits the host's bytes into command lines and :class:`SlcanProtocol`
executes them (both free of threads and I/O, so they are tested and fuzzed on their own);
:class:`SlcanAdapter` puts them on a pty and the hub. Commands run in the simulation
thread, in order with the frames the bus delivers, admitted at the serial line's rate
like any serial instrument's. ``counters`` (display only): frames the host sent (accepted
``t`` commands) and frames delivered to it, bytes both ways, the last command line.
"""

from __future__ import annotations

import logging
import re
import time
from collections.abc import Callable
from pathlib import Path

from station.hil import throttle
from station.hil.can_hub import CanHub
from station.hil.counters import LinkCounters, short
from station.hil.links_dir import DirHandle
from station.hil.pty_port import PtyPort

log = logging.getLogger(__name__)

OK = b"\r"
ERROR = b"\a"
MAX_LINE = 64
MAX_BACKLOG = 1024  # bytes posted to the simulation thread and not yet applied
_FRAME = re.compile(r"t([0-9A-Fa-f]{3})([0-8])((?:[0-9A-Fa-f]{2})*)")
TOO_LONG = None  # what SlcanLines yields for an over-long line


def format_frame(arbitration_id: int, data: bytes) -> bytes:
    """``tIIIL<data>`` CR for a standard data frame."""
    return f"t{arbitration_id & 0x7FF:03X}{len(data)}{data.hex().upper()}\r".encode("ascii")


class SlcanLines:
    """Host bytes -> command lines (CR or LF ended; a CR LF pair is one end). A line longer
    than ``MAX_LINE`` bytes yields ``TOO_LONG`` once, and its bytes up to the end of the
    line are dropped, however they arrive."""

    def __init__(self) -> None:
        self._line = bytearray()
        self._discarding = False
        self._after_cr = False

    def feed(self, data: bytes) -> list[bytes | None]:
        out: list[bytes | None] = []
        for b in data:
            if b in (0x0D, 0x0A):
                if b == 0x0A and self._after_cr:
                    self._after_cr = False
                    continue  # the LF of a CR LF pair
                self._after_cr = b == 0x0D
                if self._discarding:
                    self._discarding = False  # the end of a refused line
                else:
                    out.append(bytes(self._line))
                self._line.clear()
                continue
            self._after_cr = False
            if self._discarding:
                continue
            if len(self._line) < MAX_LINE:
                self._line.append(b)
            else:
                self._line.clear()
                self._discarding = True
                out.append(TOO_LONG)
        return out


class SlcanProtocol:
    """The adapter's state and its answer to each command line (simulation thread).

    ``on_frame(arbitration_id, data)`` puts a host frame on the bus; ``on_close()`` drops
    frames still queued for the host."""

    def __init__(self, on_frame: Callable[[int, bytes], None],
                 on_close: Callable[[], None] = lambda: None) -> None:
        self.on_frame = on_frame
        self.on_close = on_close
        self.is_open = False
        self.listen_only = False
        self.frames_sent = 0

    def execute(self, raw: bytes | None) -> bytes:
        """Answer one command line (``TOO_LONG``: an over-long line, refused)."""
        if raw is None:
            return ERROR
        try:
            line = raw.decode("ascii")
        except UnicodeDecodeError:
            return ERROR
        if not line.isprintable():
            return ERROR
        return self._execute(line.strip())

    def _execute(self, line: str) -> bytes:
        if not line:
            return OK
        c, rest = line[0], line[1:]
        if c in "OLCVNF" and rest:  # these take no argument
            return ERROR
        if c in "OL":  # open; L: listen only (the host may not send)
            self.is_open = True
            self.listen_only = c == "L"
            return OK
        if c == "C":
            self.is_open = False
            self.listen_only = False
            self.on_close()
            return OK
        if c in "SY":  # S0..S9: the standard bit rates (python-can's table); Y: FD data rate
            return OK if not self.is_open and len(rest) == 1 and rest.isdigit() else ERROR
        if c == "s":  # BTR0 BTR1 as four hex digits
            return OK if not self.is_open and _hex(rest, 4) else ERROR
        if c == "V":
            return b"V1013\r"
        if c == "N":
            return b"NSIM1\r"
        if c == "F":
            return b"F00\r"
        if c in "ZXQW":  # timestamps, auto poll, auto startup, filter mode: one digit
            return OK if rest in ("0", "1", "2") else ERROR
        if c in "Mm":  # acceptance code / mask, 8 hex digits
            return OK if _hex(rest, 8) else ERROR
        if c == "t":
            m = _FRAME.fullmatch(line)
            if not self.is_open or self.listen_only:
                return ERROR
            if m is None or len(m.group(3)) != 2 * int(m.group(2)):
                return ERROR
            ident = int(m.group(1), 16)
            if ident > 0x7FF:  # three hex digits, but a standard identifier has 11 bits
                return ERROR
            self.on_frame(ident, bytes.fromhex(m.group(3)))
            self.frames_sent += 1
            return b"z\r"
        # T/r/R/d/D/b/B: extended, remote and FD frames do not exist on the IEU bus
        return ERROR


def _hex(s: str, n: int) -> bool:
    return len(s) == n and all(c in "0123456789abcdefABCDEF" for c in s)


class SlcanAdapter:
    """One slcan adapter on the hub, served on a raw pty."""

    def __init__(self, hub: CanHub, name: str, link: Path | None,
                 directory: DirHandle | None = None,
                 rate: throttle.Rate = throttle.SERIAL) -> None:
        self.hub = hub
        self.env = hub.env
        self.protocol = SlcanProtocol(self._on_frame, self._discard)
        self.lines = SlcanLines()  # reader thread only
        self.posted = 0  # bytes handed to the simulation thread (reader thread)
        self.applied = 0  # of those, bytes executed (simulation thread)
        self.refusals = throttle.LogLimiter(log)  # simulation thread
        self.port = PtyPort(name, self._from_host, link,
                            admit=throttle.TokenBucket.of(rate, self.env.speed, time.monotonic()),
                            slice_bytes=rate.slice, ready=self._keeping_up, directory=directory)
        self.counters = LinkCounters()
        hub.attach(self)

    @property
    def address(self) -> str:
        return self.port.address

    @property
    def is_open(self) -> bool:
        return self.protocol.is_open

    def start(self) -> None:
        self.port.start()

    def close(self) -> None:
        self.hub.detach(self)
        self.port.close()

    def _keeping_up(self) -> bool:
        return self.posted - self.applied < MAX_BACKLOG

    def _on_frame(self, arbitration_id: int, data: bytes) -> None:
        """Simulation thread: a host frame onto the bus (counted first: the IEU may answer
        it, and the answer reach the host, at once)."""
        self.counters.rx_msgs += 1
        self.hub.on_bus(self, arbitration_id, data)

    def _discard(self) -> None:
        self.port.discard_output()

    # ----- host to bus -----
    def _from_host(self, data: bytes) -> None:
        """Reader thread: split into CR-terminated commands and post them, in order."""
        self.counters.rx_bytes += len(data)
        self.counters.touch()
        lines = self.lines.feed(data)
        for line in lines:
            if line:
                self.counters.last_msg = short(line)
        self.posted += len(data)
        self.env.post(lambda: self._commands(lines, len(data)))

    def _commands(self, lines: list[bytes | None], size: int) -> None:
        """Simulation thread: execute command lines and answer each."""
        self.applied += size
        for raw in lines:
            reply = self.protocol.execute(raw)  # a frame sent is counted by _on_frame
            if reply == ERROR:
                what = "an over-long line" if raw is None else repr(raw[:20])
                self.refusals.info(time.monotonic(), "slcan %s: refused %s", self.port.name,
                                   what)
            self._write(reply)

    def _write(self, data: bytes) -> None:
        """Simulation thread: bytes to the host."""
        self.counters.tx_bytes += len(data)  # counted first: the write may reach the host at once
        self.port.write(data)

    # ----- bus to host -----
    def deliver(self, t: float, arbitration_id: int, data: bytes) -> None:
        if self.protocol.is_open:
            self.counters.tx_msgs += 1
            self.counters.touch()
            self._write(format_frame(arbitration_id, data))
