"""How much a host may make the server do: the line rate a link admits host bytes at, and
how often a link may log what it refused.

A real RS-232 line at 115200 baud (8N1: 10 bits a byte) carries 11,520 bytes per second,
and a CAN bus at 1 Mbit/s about 7,700 frames; a host that writes faster only fills its
own buffers. Each link of the server admits its host's input at that rate (a token bucket
of the rack's time, so a rehearsal at ``speed`` X admits X times as much per wall second),
in slices of at most ``slice`` bytes, and never more per wall second than ``wall_cap``: the
share of the single simulation thread one link may claim. A flood on one link is thus
processed in bounded slices between everybody else's input, and cannot make the
simulation fall behind. Time is passed in (``now``, monotonic seconds), so the arithmetic
is tested without a clock.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

SERIAL_BYTES_PER_S = 11_520.0  # 115200 baud, 10 bits a byte
CAN_FRAMES_PER_S = 7_700.0  # 1 Mbit/s, a standard 8-byte frame ~130 bits with stuffing
SOCKETCAND_BYTES_PER_FRAME = 40.0  # "< send 7FF 8 FF FF FF FF FF FF FF FF >"


@dataclass(frozen=True)
class Rate:
    """A link's admission: ``per_s`` units per second of the rack's time, at most
    ``wall_cap`` per wall second, ``burst`` at once after a quiet spell, taken in slices
    of at most ``slice`` (a read never asks the OS for more)."""

    per_s: float
    wall_cap: float
    burst: float
    slice: int

    def wall_rate(self, speed: float) -> float:
        """Units per wall second at ``speed`` simulated seconds per wall second."""
        return min(self.per_s * speed, self.wall_cap)


SERIAL = Rate(SERIAL_BYTES_PER_S, wall_cap=65_536.0, burst=256.0, slice=64)
SOCKETCAND_BYTES = Rate(CAN_FRAMES_PER_S * SOCKETCAND_BYTES_PER_FRAME, wall_cap=65_536.0,
                        burst=1024.0, slice=256)
SOCKETCAND_FRAMES = Rate(CAN_FRAMES_PER_S, wall_cap=2_000.0, burst=16.0, slice=1)


class TokenBucket:
    """Units a link may take now: ``rate`` per second up to ``burst`` held (see module doc)."""

    def __init__(self, rate: float, burst: float, now: float) -> None:
        if not (rate > 0 and math.isfinite(rate)) or not burst >= 1:
            raise ValueError(f"a token bucket needs a positive rate and a burst >= 1, got "
                             f"rate {rate}, burst {burst}")
        self.rate = float(rate)
        self.burst = float(burst)
        self._tokens = float(burst)
        self._at = now

    @classmethod
    def of(cls, rate: Rate, speed: float, now: float) -> TokenBucket:
        return cls(rate.wall_rate(speed), rate.burst, now)

    def available(self, now: float) -> float:
        """Units that may be taken at ``now`` (time never runs backwards here)."""
        if now > self._at:
            self._tokens = min(self.burst, self._tokens + (now - self._at) * self.rate)
            self._at = now
        return self._tokens

    def take(self, n: float, now: float) -> None:
        """Spend ``n`` units (the bucket may go into debt: the next wait pays it back)."""
        self.available(now)
        self._tokens -= n

    def wait_s(self, need: float, now: float) -> float:
        """Seconds from ``now`` until ``need`` units (at most ``burst``) are available."""
        short = min(need, self.burst) - self.available(now)
        return max(0.0, short / self.rate)


class LogLimiter:
    """At most one log record per ``every_s`` seconds per link; the rest are counted and
    reported with the next record, so a flood of refused input cannot flood the log."""

    def __init__(self, log: logging.Logger, every_s: float = 1.0) -> None:
        self.log = log
        self.every_s = every_s
        self.suppressed = 0
        self._next = -math.inf

    def info(self, now: float, msg: str, *args: object) -> None:
        if now < self._next:
            self.suppressed += 1
            return
        self._next = now + self.every_s
        if self.suppressed:
            msg += " (and %d more refused since the last report)"
            args = (*args, self.suppressed)
            self.suppressed = 0
        self.log.info(msg, *args)
