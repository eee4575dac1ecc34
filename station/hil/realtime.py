"""A simpy environment paced to the wall clock, into which other threads inject host input.

Simulated time (integer ns ticks) runs at ``speed`` simulated seconds per wall second. The
simulation thread sleeps on an input queue until the next event is due, so input posted by
an I/O thread wakes it at once and is applied *in the simulation thread* at the tick that
corresponds to its wall arrival time (DESIGN.md, "Time"). When the physics cannot keep up,
input is applied at the simulation's frontier instead (see ``_schedule``), so replies stay
prompt, and the wall-to-tick mapping slips so that the simulation never trails the wall
clock by more than ``max_lag_s`` (no sprint to catch up afterwards); the slip is counted.
"""

from __future__ import annotations

import math
import queue
import time
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any, TypeVar

import simpy

from sim.timebase import TICKS_PER_SECOND, seconds

T = TypeVar("T")
MAX_WAIT_S = 60.0  # longest single wait for the next event (the lock timeout has a maximum)
_STOP = object()


class RealtimeEnv(simpy.Environment):
    """simpy environment run in real time (times ``speed``) with a thread-safe input queue."""

    def __init__(self, speed: float = 1.0, max_lag_s: float = 0.05, initial_time: int = 0):
        if not speed > 0 or not math.isfinite(speed):
            raise ValueError(f"speed must be a positive number, got {speed}")
        super().__init__(initial_time)
        self.speed = float(speed)
        self.max_lag_s = float(max_lag_s)
        self._inputs: queue.SimpleQueue = queue.SimpleQueue()
        self._ticks_per_wall_s = self.speed * TICKS_PER_SECOND
        self._wall0 = time.monotonic()
        self._tick0 = self.now
        self.slipped_s = 0.0  # wall seconds the mapping slipped because the physics lagged
        self.inputs_applied = 0
        self.running = False
        self._last_input_tick = initial_time  # inputs apply in the order they arrived

    # ----- wall <-> tick mapping (simulation thread only) -----
    def tick_at(self, wall: float) -> int:
        """Simulated tick that corresponds to a monotonic wall time."""
        return int(self._tick0) + math.floor((wall - self._wall0) * self._ticks_per_wall_s)

    def wall_at(self, tick: int | float) -> float:
        """Monotonic wall time at which a simulated tick is due."""
        return self._wall0 + (tick - self._tick0) / self._ticks_per_wall_s

    def _anchor(self) -> None:
        self._wall0 = time.monotonic()
        self._tick0 = self.now

    # ----- any thread -----
    def post(self, fn: Callable[[], Any]) -> None:
        """Run ``fn()`` in the simulation thread at the simulated time of this call."""
        self._inputs.put((time.monotonic(), fn, None))

    def call(self, fn: Callable[[], T], timeout: float | None = 5.0) -> T:
        """Run ``fn()`` in the sim thread at this call's simulated time; return the result.

        For other threads only: called from the simulation thread it would wait for itself.
        """
        fut: Future = Future()
        self._inputs.put((time.monotonic(), fn, fut))
        return fut.result(timeout)

    def stop(self) -> None:
        """Make :meth:`run_realtime` return (any thread)."""
        self._inputs.put(_STOP)

    @property
    def now_s(self) -> float:
        """Simulated seconds (a float, for display)."""
        return seconds(int(self.now))

    # ----- simulation thread -----
    def run_realtime(self) -> None:
        """Process events as the wall clock reaches them and apply posted input until stopped."""
        self._anchor()
        self.running = True
        try:
            while True:
                if self._drain():
                    return
                nxt = self.peek()
                wait = None
                if nxt != math.inf:
                    late = time.monotonic() - self.wall_at(nxt)
                    if late >= 0:
                        if late > self.max_lag_s:
                            slip = late - self.max_lag_s
                            self._wall0 += slip
                            self.slipped_s += slip
                        self.step()
                        continue
                    wait = min(-late, MAX_WAIT_S)
                try:
                    item = self._inputs.get(timeout=wait)
                except queue.Empty:
                    continue
                if item is _STOP:
                    return
                self._schedule(item)
        finally:
            self.running = False

    def _drain(self) -> bool:
        """Schedule every input already queued; True if a stop was requested."""
        while True:
            try:
                item = self._inputs.get_nowait()
            except queue.Empty:
                return False
            if item is _STOP:
                return True
            self._schedule(item)

    def _schedule(self, item: tuple[float, Callable[[], Any], Future | None]) -> None:
        """Queue ``fn`` as an event at the simulated time of its arrival (never in the past).

        That is the tick its wall arrival maps to; but if the physics lags and events before
        that tick are still unprocessed, it is the simulation's frontier (the next event):
        the host cannot have seen anything later, and the reply is not held up by the lag.
        Never before an input that arrived earlier (the mapping moves back when it slips),
        so the bytes of one link reach its instrument in the order they were sent.
        """
        wall, fn, fut = item
        tick = max(min(self.tick_at(wall), self.peek()), self._last_input_tick, self.now)
        self._last_input_tick = int(tick)
        delay = int(tick) - self.now

        def apply(_ev: simpy.Event) -> None:
            self.inputs_applied += 1
            if fut is None:
                fn()  # an exception here is a simulator bug: it stops the server loudly
            elif fut.set_running_or_notify_cancel():
                try:
                    fut.set_result(fn())
                except Exception as e:  # handed to the caller of call()
                    fut.set_exception(e)

        self.timeout(delay).callbacks.append(apply)
