"""The station clock: the only time a procedure or driver sees.

VirtualClock advances the simulation inline (sleep steps simpy); WallClock is real time
for hardware-in-the-loop runs against a served rack or real instruments.
"""

from __future__ import annotations

import time
from typing import Protocol

import simpy

from sim.timebase import seconds
from station.links.virtual import run_until


class Clock(Protocol):
    def now(self) -> float: ...

    def sleep(self, s: float) -> None: ...


class VirtualClock:
    """Simulated seconds since the start of the run."""

    virtual = True

    def __init__(self, env: simpy.Environment) -> None:
        self.env = env

    def now(self) -> float:
        return seconds(self.env.now)

    def sleep(self, s: float) -> None:
        if s > 0:
            run_until(self.env, lambda: False, s)


class WallClock:
    """Monotonic wall seconds since the clock was made (HIL and real hardware)."""

    virtual = False

    def __init__(self) -> None:
        self._t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self._t0

    def sleep(self, s: float) -> None:
        if s > 0:
            time.sleep(s)
