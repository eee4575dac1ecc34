"""An slcan (Lawicel ASCII) CAN adapter on a pty, for python-can's ``interface="slcan"``.

Commands end with CR; the adapter answers CR for OK and BEL for an error. python-can opens
with ``C``, ``S<n>``, an empty line, ``O`` and ``O`` again (the second ``O`` is accepted,
not refused, since python-can always sends it). Frames: ``tIIIL<data hex>`` (standard data
frames only: the IEU bus carries nothing else); a sent frame is acknowledged ``z`` CR as by
a Lawicel adapter. Frames reach the host only while the channel is open; ``C`` also drops
frames still queued for the host (pyserial's flush on open clears the pty itself). Commands
run in the simulation thread, in order with the frames the bus delivers. ``counters``
(display only): frames the host sent (accepted ``t`` commands) and frames delivered to it,
bytes both ways, the last command line.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

from station.hil.can_hub import CanHub
from station.hil.pty_port import PtyPort
from station.hil.status import LinkCounters, short

log = logging.getLogger(__name__)

OK = b"\r"
ERROR = b"\a"
MAX_LINE = 64
_FRAME = re.compile(r"t([0-9A-Fa-f]{3})([0-8])([0-9A-Fa-f]*)")


def format_frame(arbitration_id: int, data: bytes) -> bytes:
    """``tIIIL<data>`` CR for a standard data frame."""
    return f"t{arbitration_id & 0x7FF:03X}{len(data)}{data.hex().upper()}\r".encode("ascii")


class SlcanAdapter:
    """One slcan adapter on the hub, served on a raw pty."""

    def __init__(self, hub: CanHub, name: str, link: Path | None) -> None:
        self.hub = hub
        self.env = hub.env
        self.port = PtyPort(name, self._from_host, link)
        self.is_open = False  # simulation thread only
        self.listen_only = False
        self._line = bytearray()  # reader thread only
        self.counters = LinkCounters()
        hub.attach(self)

    @property
    def address(self) -> str:
        return self.port.address

    def start(self) -> None:
        self.port.start()

    def close(self) -> None:
        self.hub.detach(self)
        self.port.close()

    # ----- host to bus -----
    def _from_host(self, data: bytes) -> None:
        """Reader thread: split into CR-terminated commands and post them in order."""
        self.counters.rx_bytes += len(data)
        self.counters.touch()
        for b in data:
            if b in (0x0D, 0x0A):
                if b == 0x0A and not self._line:
                    continue  # a CR LF pair
                line = bytes(self._line)
                self._line.clear()
                if line:
                    self.counters.last_msg = short(line)
                self.env.post(lambda line=line: self._command(line))
            elif len(self._line) < MAX_LINE:
                self._line.append(b)
            else:
                self._line.clear()
                self.env.post(lambda: self._write(ERROR))

    def _command(self, raw: bytes) -> None:
        """Simulation thread: execute one command line and answer it."""
        self._write(self._execute(raw.decode("ascii", "replace").strip()))

    def _write(self, data: bytes) -> None:
        """Simulation thread: bytes to the host."""
        self.port.write(data)
        self.counters.tx_bytes += len(data)

    def _execute(self, line: str) -> bytes:
        if not line:
            return OK
        c = line[0]
        if c in "OL":  # open; L: listen only (the host may not send)
            self.is_open = True
            self.listen_only = c == "L"
            return OK
        if c == "C":
            self.is_open = False
            self.port.discard_output()
            return OK
        if c in "SsY":  # bit rates: accepted while closed, as by a real adapter
            return ERROR if self.is_open else OK
        if c == "V":
            return b"V1013\r"
        if c == "N":
            return b"NSIM1\r"
        if c == "F":
            return b"F00\r"
        if c in "ZXQWMm":
            return OK
        if c == "t":
            m = _FRAME.fullmatch(line)
            if not self.is_open or self.listen_only:
                return ERROR
            if m is None or len(m.group(3)) != 2 * int(m.group(2)):
                return ERROR
            self.hub.on_bus(self, int(m.group(1), 16), bytes.fromhex(m.group(3)))
            self.counters.rx_msgs += 1
            return b"z\r"
        # T/r/R/d/D/b/B: extended, remote and FD frames do not exist on the IEU bus
        log.info("slcan %s: refused %r", self.port.name, line[:20])
        return ERROR

    # ----- bus to host -----
    def deliver(self, t: float, arbitration_id: int, data: bytes) -> None:
        if self.is_open:
            self._write(format_frame(arbitration_id, data))
            self.counters.tx_msgs += 1
            self.counters.touch()
