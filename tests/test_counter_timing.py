"""A gate edge that lies a rounding error after a tick boundary must not stall the counter.

Seconds are floats and ticks are integers: an edge at nextafter(N / 1e9) falls on tick N
when rounded up (ticks_ceil), yet N / 1e9 < edge as floats. Comparing the two in seconds
made the counter re-plan the same gate forever (two seeds in a hundred hung that way).
"""

from __future__ import annotations

import math

import numpy as np

from sim.timebase import seconds, ticks_ceil


class EdgeGrid:
    """A gating line whose edges are t_e + j * dt, j = 0, 1, ..."""

    net = None
    bipolar_sign = 0

    def __init__(self, t_e: float, dt: float) -> None:
        self.t_e, self.dt = t_e, dt

    def estimate_edge(self, t: float, n: int) -> None:
        return None  # no estimate: the counter solves the exact edge at once

    def edge_after(self, t: float, n: int) -> float:
        j = max(0, math.floor((t - self.t_e) / self.dt) + 1) if t >= self.t_e else 0
        return self.t_e + (j + n - 1) * self.dt


def test_edge_just_after_a_tick_boundary_does_not_stall(rack, station):
    n = 30_000_123_456_780
    while True:  # find a tick whose next float lands back on it when rounded up
        t_e = float(np.nextafter(seconds(n), math.inf))
        if ticks_ceil(t_e) == n and seconds(n) < t_e:
            break
        n += 1
    station.clock.sleep(seconds(n) - 1.0)
    panel = rack.serial["patch_panel"]
    grid = EdgeGrid(t_e, 0.25)
    real = panel.source

    def source(counter, inp):
        return grid if (counter, inp) == ("C2", "Z") else real(counter, inp)

    panel.source = source
    station.patch_panel.connect("OSC1", 2, "X")
    station.patch_panel.connect("OSC1", 2, "Z")  # the patch is bypassed for Z above
    station.counters[2].set_mode("measure Z")
    station.counters[2].set_preset(4)
    station.counters[2].operate()
    ticks = station.counters[2].read(timeout=5.0)  # stalled before the fix: no reading
    assert abs(ticks - 1_000_000) <= 1  # four edges 0.25 s apart: one second of S1^T
