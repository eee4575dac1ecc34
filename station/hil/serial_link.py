"""A serial instrument served on a pty: host bytes into the simulation, replies back out.

Host bytes are posted to the simulation thread and reach ``ByteInstrument.receive`` at the
simulated time of their arrival; the instrument's output chunks go to the pty writer. The
server is the instrument's only consumer, so its ``output`` buffer is drained as it goes.
``counters`` (display only): lines and bytes from the host (reader thread), lines and bytes
to the host (simulation thread), the last command line seen.
"""

from __future__ import annotations

from pathlib import Path

from instruments.base import ByteInstrument
from station.hil.pty_port import PtyPort
from station.hil.realtime import RealtimeEnv
from station.hil.status import LinkCounters, short

MAX_SEEN = 80  # bytes of a command line kept for display


class SerialPtyLink:
    """Binds one ByteInstrument to one raw pty (build before the simulation thread starts)."""

    def __init__(self, env: RealtimeEnv, instrument: ByteInstrument, link: Path | None) -> None:
        self.env = env
        self.instrument = instrument
        self.port = PtyPort(instrument.name, self._from_host, link)
        self.counters = LinkCounters()
        self._seen = bytearray()  # reader thread: the command line being received
        instrument.listeners.append(self._to_host)

    @property
    def address(self) -> str:
        return self.port.address

    def _from_host(self, data: bytes) -> None:
        """Reader thread: hand the bytes to the simulation thread, stamped with their arrival."""
        inst = self.instrument
        self.env.post(lambda: inst.receive(data))
        c = self.counters
        c.rx_bytes += len(data)
        *complete, rest = (bytes(self._seen) + data).split(b"\n")
        if complete:
            c.rx_msgs += len(complete)
            c.last_msg = short(complete[-1][:MAX_SEEN])
        self._seen[:] = rest[:MAX_SEEN]
        c.touch()

    def _to_host(self, data: bytes) -> None:
        """Simulation thread: one chunk of instrument output."""
        self.instrument.output.clear()  # nobody else reads it; do not let it grow all day
        self.port.write(data)
        c = self.counters
        c.tx_bytes += len(data)
        c.tx_msgs += data.count(b"\n")
        c.touch()

    def start(self) -> None:
        self.port.start()

    def close(self) -> None:
        self.port.close()
