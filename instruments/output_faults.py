"""Faults on what a simulated instrument sends: replies delayed, garbled and lost, CAN frames
delayed, lost and altered; each random choice from a stream seeded by the run's seed.

The instruments hold these (``ByteInstrument.reply_fault``, ``Ieu.frame_fault``);
:mod:`instruments.faults` arms them from the configuration.
"""

from __future__ import annotations

import numpy as np

from sim.rng import stream
from sim.timebase import ticks


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
