"""The IEU's CAN bus in the server: every adapter (socketcand client, slcan pty) is a node on it.

As on a real bus, a frame from the IEU reaches every adapter, and a frame a host sends
reaches the IEU and every *other* adapter (a sniffer sees the commands too), never its own
sender. Host frames are applied in the simulation thread at their arrival time; adapters
are handed frames in the simulation thread and must only queue them.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Protocol

from instruments.isu.ieu import Ieu
from station.hil.realtime import RealtimeEnv


class CanAdapter(Protocol):
    def deliver(self, t: float, arbitration_id: int, data: bytes) -> None:
        """Queue one frame for the host (simulated time ``t`` in seconds); must not block."""


class CanHub:
    """Fan-out between the IEU and the host adapters attached to its bus."""

    def __init__(self, env: RealtimeEnv, ieu: Ieu) -> None:
        self.env = env
        self.ieu = ieu
        self._adapters: tuple[CanAdapter, ...] = ()
        self._lock = threading.Lock()
        ieu.listeners.append(self._from_device)

    def attach(self, adapter: CanAdapter) -> None:
        with self._lock:
            self._adapters = (*self._adapters, adapter)

    def detach(self, adapter: CanAdapter) -> None:
        with self._lock:
            self._adapters = tuple(a for a in self._adapters if a is not adapter)

    def send(self, sender: CanAdapter, arbitration_id: int, data: bytes,
             applied: Callable[[], None] | None = None) -> None:
        """A host frame (any thread): onto the bus at the simulated time of its arrival;
        ``applied()`` is called in the simulation thread once it is on the bus."""
        frame = bytes(data)

        def apply() -> None:
            if applied is not None:
                applied()
            self.on_bus(sender, arbitration_id, frame)

        self.env.post(apply)

    def on_bus(self, sender: CanAdapter, arbitration_id: int, data: bytes) -> None:
        """A host frame, in the simulation thread: to the other adapters and to the IEU."""
        t = self.env.now_s
        for a in self._adapters:
            if a is not sender:
                a.deliver(t, arbitration_id, data)
        self.ieu.receive_frame(arbitration_id, data)

    def _from_device(self, t: float, arbitration_id: int, data: bytes) -> None:
        self.ieu.output.clear()  # the hub is the IEU's only consumer here
        for a in self._adapters:
            a.deliver(t, arbitration_id, data)
