"""In-process virtual links: endpoints of the simulated racks, and inline stepping of simpy.

A blocking read on a virtual link steps the simulation in the reading thread until the
awaited bytes or frames exist, or until the timeout expires in simulated time (DESIGN.md).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Protocol
from urllib.parse import parse_qs, urlparse

import simpy

from sim.timebase import ticks
from station.errors import Deadlock

LIVELOCK_STEPS = 1_000_000  # events at one instant before a wait is declared stuck


class SerialEndpoint(Protocol):
    """A simulated serial instrument as its link sees it: bytes in, a buffer of bytes out."""

    output: bytearray

    def receive(self, data: bytes) -> None: ...


class CanEndpoint(Protocol):
    """A simulated CAN instrument as its bus sees it: frames in, (time s, id, data) out."""

    output: deque[tuple[float, int, bytes]]

    def receive_frame(self, arbitration_id: int, data: bytes) -> None: ...


@dataclass
class VirtualRack:
    rack_id: str
    env: simpy.Environment
    serial: Mapping[str, SerialEndpoint] = field(default_factory=dict)
    can: Mapping[str, CanEndpoint] = field(default_factory=dict)


_racks: dict[str, VirtualRack] = {}
_current: list[str] = []


def register(rack: VirtualRack) -> None:
    _racks[rack.rack_id] = rack
    _current.append(rack.rack_id)


def unregister(rack_id: str) -> None:
    _racks.pop(rack_id, None)
    while rack_id in _current:
        _current.remove(rack_id)


def _rack(rack_id: str | None) -> VirtualRack:
    rid = rack_id or (_current[-1] if _current else None)
    if rid is None or rid not in _racks:
        raise LookupError(
            f"no simulated rack '{rid}' in this process" if rid else "no simulated rack running"
        )
    return _racks[rid]


def resolve_serial(url: str) -> tuple[SerialEndpoint, simpy.Environment]:
    """Endpoint for ``sim://NAME[?rack=ID]``."""
    u = urlparse(url)
    rack_id = parse_qs(u.query).get("rack", [None])[0]
    rack = _rack(rack_id)
    name = u.netloc or u.path.lstrip("/")
    if name not in rack.serial:
        raise LookupError(f"no simulated serial instrument '{name}' in rack {rack.rack_id}")
    return rack.serial[name], rack.env


def resolve_can(channel: str, rack_id: str | None) -> tuple[CanEndpoint, simpy.Environment]:
    rack = _rack(rack_id)
    if channel not in rack.can:
        raise LookupError(f"no simulated CAN channel '{channel}' in rack {rack.rack_id}")
    return rack.can[channel], rack.env


def run_until(env: simpy.Environment, done: Callable[[], bool], timeout_s: float | None) -> bool:
    """Step ``env`` until ``done()`` or until ``timeout_s`` simulated seconds have passed."""
    if done():
        return True
    deadline = None if timeout_s is None else int(env.now) + ticks(timeout_s)
    still, last = 0, env.now
    queue, step = env._queue, env.step  # simpy's own peek() and step(), looked up once
    while True:
        nxt = queue[0][0] if queue else math.inf
        if deadline is not None and nxt > deadline:
            advance_to(env, deadline)  # nothing is scheduled up to it: env.run(until=)
            return done()  # without its stop event (issue 17)
        if nxt == math.inf:
            raise Deadlock("waiting with nothing scheduled in the simulation")
        step()
        if env._now == last:
            still += 1
            if still > LIVELOCK_STEPS:
                raise Deadlock(f"simulation stuck at t = {env.now} ns: {still} events "
                               "without time advancing (livelock)")
        else:
            still, last = 0, env._now
        if done():
            return True


def advance_to(env: simpy.Environment, at: int) -> None:
    """Bring ``env`` to ``at`` ticks: every event before it happens, then the clock stands
    at ``at`` with nothing scheduled for that instant yet run. The same as a timeout ending
    at ``at`` would do, without the event (a frame stamped ahead of the clock, see
    ``SimBus.recv``)."""
    if env.peek() < at:
        run_until(env, lambda: env.peek() >= at, None)
    if at > env.now:
        env._now = at  # simpy keeps its clock here; nothing is scheduled before ``at``

