"""A serial instrument served on a pty: host bytes into the simulation, replies back out.

Host bytes are posted to the simulation thread and reach ``ByteInstrument.receive`` at the
simulated time of their arrival; the instrument's output chunks go to the pty writer. The
server is the instrument's only consumer, so its ``output`` buffer is drained as it goes.
Host bytes are admitted at the serial line's rate in small slices (``throttle.SERIAL``),
and no more are taken from the pty while ``MAX_BACKLOG`` bytes wait for the simulation
thread: a flood on this link is processed in bounded slices and queues in the host's own
buffers, not in the server.
``counters`` (display only): lines and bytes from the host (reader thread), lines and bytes
to the host (simulation thread), the last command line seen.
"""

from __future__ import annotations

import time
from pathlib import Path

from instruments.base import ByteInstrument
from station.hil import throttle
from station.hil.counters import LinkCounters, short
from station.hil.links_dir import DirHandle
from station.hil.pty_port import PtyPort
from station.hil.realtime import RealtimeEnv

MAX_SEEN = 80  # bytes of a command line kept for display
MAX_BACKLOG = 1024  # bytes posted to the simulation thread and not yet applied


class SerialPtyLink:
    """Binds one ByteInstrument to one raw pty (build before the simulation thread starts)."""

    def __init__(self, env: RealtimeEnv, instrument: ByteInstrument, link: Path | None,
                 directory: DirHandle | None = None,
                 rate: throttle.Rate = throttle.SERIAL) -> None:
        self.env = env
        self.instrument = instrument
        self.posted = 0  # bytes handed to the simulation thread (reader thread)
        self.applied = 0  # of those, bytes the instrument has received (simulation thread)
        self.port = PtyPort(instrument.name, self._from_host, link,
                            admit=throttle.TokenBucket.of(rate, env.speed, time.monotonic()),
                            slice_bytes=rate.slice, ready=self._keeping_up, directory=directory)
        self.counters = LinkCounters()
        self._seen = bytearray()  # reader thread: the command line being received
        instrument.listeners.append(self._to_host)

    def _keeping_up(self) -> bool:
        """Reader thread: the simulation thread has applied all but a little of our input."""
        return self.posted - self.applied < MAX_BACKLOG

    @property
    def address(self) -> str:
        return self.port.address

    def _from_host(self, data: bytes) -> None:
        """Reader thread: hand the bytes to the simulation thread, stamped with their arrival."""
        c = self.counters  # counted first: the reply may reach the host before we return
        c.rx_bytes += len(data)
        *complete, rest = (bytes(self._seen) + data).split(b"\n")
        if complete:
            c.rx_msgs += len(complete)
            c.last_msg = short(complete[-1][:MAX_SEEN])
        self._seen[:] = rest[:MAX_SEEN]
        c.touch()
        self.posted += len(data)
        self.env.post(lambda: self._apply(data))

    def _apply(self, data: bytes) -> None:
        """Simulation thread: the host's bytes reach the instrument."""
        self.applied += len(data)
        self.instrument.receive(data)

    def _to_host(self, data: bytes) -> None:
        """Simulation thread: one chunk of instrument output."""
        self.instrument.output.clear()  # nobody else reads it; do not let it grow all day
        c = self.counters  # counted first: the write may reach the host at once
        c.tx_bytes += len(data)
        c.tx_msgs += data.count(b"\n")
        c.touch()
        self.port.write(data)

    def start(self) -> None:
        self.port.start()

    def close(self) -> None:
        self.port.close()
