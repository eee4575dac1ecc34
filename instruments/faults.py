"""Fault injection for rehearsals: simulated instruments that misbehave as configured.

The faults act inside the instruments, never in the links, so a rack stepped in virtual
time (``station day``) and the same rack served in real time over ptys and CAN misbehave
alike. Every random choice draws from a :func:`sim.rng.stream` named after the instrument
and the fault, so the same seed and configuration give the same faults, byte for byte,
whatever else the run does.

Serial instruments: each reply is delayed by ``latency_s`` more, each of its bytes may get
one bit flipped (``corrupt_rate``) and may then be lost (``drop_rate``). The IEU: each frame
it sends is delayed, may be lost, and may have one data byte altered. ``silent_after_s``
stops an instrument sending anything from then on (it still listens). The table's
``stall_axis`` seizes one drive at ``stall_after_s``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import partial
from typing import Protocol

import numpy as np
import simpy

from instruments.base import ByteInstrument
from instruments.isu.ieu import Ieu
from instruments.isu.table_controller import TableController
from sim.rng import stream
from sim.timebase import ticks


class FaultSettings(Protocol):
    """One instrument's faults (``station.config.isu.FaultSpec`` is one; defaults mean none)."""

    latency_s: float
    drop_rate: float
    corrupt_rate: float
    silent_after_s: float | None
    stall_axis: int | None
    stall_after_s: float


class _LossyOutput:
    """Rates and seeded streams shared by the reply and frame faults."""

    def __init__(self, name: str, seed: int, latency_s: float, drop_rate: float,
                 corrupt_rate: float) -> None:
        self.latency_s = latency_s
        self.drop_rate = drop_rate
        self.corrupt_rate = corrupt_rate
        self._drop = stream(seed, "faults", name, "drop")
        self._corrupt = stream(seed, "faults", name, "corrupt")


class ReplyFault(_LossyOutput):
    """Delays, garbles and loses the reply bytes of one serial instrument."""

    def __init__(self, name: str, seed: int, latency_s: float, drop_rate: float,
                 corrupt_rate: float) -> None:
        super().__init__(name, seed, latency_s, drop_rate, corrupt_rate)
        self.latency = ticks(latency_s)  # extra ticks before each reply
        self.bytes_seen = 0
        self.bytes_corrupted = 0
        self.bytes_dropped = 0

    def garble(self, data: bytes) -> bytes:
        """The bytes that reach the link: some with one bit flipped, some lost."""
        if not (self.corrupt_rate or self.drop_rate):
            return data
        buf = np.frombuffer(data, dtype=np.uint8).copy()
        self.bytes_seen += buf.size
        if self.corrupt_rate:
            hit = self._corrupt.random(buf.size) < self.corrupt_rate
            n = int(hit.sum())
            bits = self._corrupt.integers(0, 8, size=n)
            buf[hit] ^= np.left_shift(1, bits).astype(np.uint8)
            self.bytes_corrupted += n
        if self.drop_rate:
            keep = self._drop.random(buf.size) >= self.drop_rate
            self.bytes_dropped += int(buf.size - keep.sum())
            buf = buf[keep]
        return buf.tobytes()


class FrameFault(_LossyOutput):
    """Delays (``latency_s`` added to each send time), loses and alters the IEU's frames."""

    def __init__(self, name: str, seed: int, latency_s: float, drop_rate: float,
                 corrupt_rate: float) -> None:
        super().__init__(name, seed, latency_s, drop_rate, corrupt_rate)
        self.frames_seen = 0
        self.frames_dropped = 0
        self.frames_corrupted = 0

    def frame(self, data: bytes) -> bytes | None:
        """The frame's data as it goes on the bus, or None if the frame is lost."""
        self.frames_seen += 1
        if self.drop_rate and self._drop.random() < self.drop_rate:
            self.frames_dropped += 1
            return None
        if self.corrupt_rate and data and self._corrupt.random() < self.corrupt_rate:
            i = int(self._corrupt.integers(len(data)))
            out = bytearray(data)
            out[i] ^= int(self._corrupt.integers(1, 256))  # never zero: the byte does change
            self.frames_corrupted += 1
            return bytes(out)
        return data


def at(env: simpy.Environment, t_s: float, action: Callable[[], None]) -> None:
    """Run ``action`` at simulated time ``t_s`` (at once if that time has passed)."""
    t = ticks(t_s)
    if env.now >= t:
        action()
        return

    def wait():
        yield env.timeout(t - env.now)
        action()

    env.process(wait())


def _silence(inst: ByteInstrument | Ieu) -> Callable[[], None]:
    def action() -> None:
        inst.silent = True

    return action


def apply_faults(serial: Mapping[str, ByteInstrument], ieu: Ieu,
                 faults: Mapping[str, FaultSettings], seed: int) -> None:
    """Arm each configured fault on its instrument; nothing at all when ``faults`` is empty."""
    env = ieu.env
    for name, f in faults.items():
        if name == ieu.name:
            inst: ByteInstrument | Ieu = ieu
        elif name in serial:
            inst = serial[name]
        else:
            raise ValueError(f"fault for unknown instrument {name!r}")
        if f.latency_s or f.drop_rate or f.corrupt_rate:
            if isinstance(inst, Ieu):
                inst.frame_fault = FrameFault(name, seed, f.latency_s, f.drop_rate, f.corrupt_rate)
            else:
                inst.reply_fault = ReplyFault(name, seed, f.latency_s, f.drop_rate, f.corrupt_rate)
        if f.silent_after_s is not None:
            at(env, f.silent_after_s, _silence(inst))
        if f.stall_axis is not None:
            if not isinstance(inst, TableController):
                raise ValueError(f"{name} has no axis to stall")
            at(env, f.stall_after_s, partial(inst.stall, f.stall_axis))
