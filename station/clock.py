"""The station clock: the only time a procedure or driver sees.

VirtualClock advances the simulation inline (sleep steps simpy); WallClock is real time
for hardware-in-the-loop runs against a served rack or real instruments. A served rack may
run ``speed`` times faster than the wall: a WallClock told its speed and time origin counts
the rack's simulated seconds, so procedures keep their own units unchanged.
"""

from __future__ import annotations

import time
from typing import Protocol

import simpy

from sim.timebase import seconds
from station.links.virtual import run_until

MIN_LINK_TIMEOUT_S = 1.0  # wall seconds a link is always given for a reply (round trip, load)


class Clock(Protocol):
    virtual: bool

    def now(self) -> float: ...

    def sleep(self, s: float) -> None: ...

    def link_seconds(self, s: float) -> float: ...


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

    def link_seconds(self, s: float) -> float:
        """Virtual links count their timeouts in simulated seconds already."""
        return s


class WallClock:
    """Real time scaled by ``speed``: seconds of the rack's (or the lab's) time.

    ``t0_monotonic`` is the ``time.monotonic()`` reading at which the rack's time was zero
    (a served rack publishes it; CLOCK_MONOTONIC is shared by the processes of one machine);
    without it the clock starts at zero when made (real hardware).
    """

    virtual = False

    def __init__(self, speed: float = 1.0, t0_monotonic: float | None = None) -> None:
        if not speed > 0:
            raise ValueError(f"clock speed must be positive, got {speed}")
        self.speed = float(speed)
        self._t0 = time.monotonic() if t0_monotonic is None else float(t0_monotonic)

    def now(self) -> float:
        return (time.monotonic() - self._t0) * self.speed

    def sleep(self, s: float) -> None:
        if s > 0:
            time.sleep(s / self.speed)

    def link_seconds(self, s: float) -> float:
        """Wall timeout for a wait of ``s`` rack seconds; never under a link's round trip."""
        return max(s / self.speed, min(s, MIN_LINK_TIMEOUT_S))
