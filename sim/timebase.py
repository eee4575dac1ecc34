"""Integer time base of the simulation: 1 tick = 1 ns.

Floats drift when gate times are built by repeated addition (DESIGN.md); simpy's clock is
therefore kept in integer nanoseconds and converted to seconds only for physics.
"""

from __future__ import annotations

import math

TICKS_PER_SECOND = 1_000_000_000


def ticks(seconds: float) -> int:
    """Nearest tick to a time in seconds."""
    return int(round(seconds * TICKS_PER_SECOND))


def ticks_ceil(seconds: float) -> int:
    """First tick at or after a time in seconds (an event must not fire before its edge)."""
    return int(math.ceil(seconds * TICKS_PER_SECOND - 1e-6))


def seconds(t: float) -> float:
    """Ticks to seconds (simpy types its clock as int | float; the station's is int ticks)."""
    return t / TICKS_PER_SECOND
