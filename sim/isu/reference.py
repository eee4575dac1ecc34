"""Pulse-by-pulse reference generator, for checking the analytic counters on short spans.

It integrates a line's instantaneous rate on a fine grid by the trapezoid rule (a path
independent of sim.isu.integrator), finds every integer crossing of the phase, and fires one
simpy event per pulse: exactly what DESIGN.md forbids for production runs, and therefore
the right yardstick for them.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import Any

import numpy as np
import simpy

from sim import units
from sim.isu.world import World


def string_phase_grid(world: World, k: int, s: int, t0: float, t1: float, dt: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Times and phase (cycles) of accelerometer k+1, string s, by direct integration."""
    n = max(2, int(math.ceil((t1 - t0) / dt)) + 1)
    t = np.linspace(t0, t1, n)
    acc = world.isu.accels[k]
    t_be, _, a_b = world.kinematics(t)
    vib = np.einsum("nij,nj->ni", t_be, world.environment.vibration_accel(t))
    a_tot = a_b + vib
    u = (a_tot @ acc.A) / units.G0
    diff_rate = acc.D1 * (u + acc.D0 + acc.D2 * u * u + acc.D3 * u**3)
    u0 = (a_b @ acc.A) / units.G0  # common mode is computed on the static part, as in sim.isu.world
    common_rate = acc.kappa * u0 * u0
    sign = -0.5 if s == 1 else 0.5
    rate = acc.f0 + common_rate + sign * diff_rate
    cum = np.concatenate(([0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))))
    ph0 = world.string_phase(k, s, t0)
    noise = acc.D1 * (acc.noise.value(t) - acc.noise.value(t0)) / units.G0
    return t, ph0 + cum + sign * noise


def crossings(t: np.ndarray, ph: np.ndarray) -> np.ndarray:
    """Times where the phase passes each integer (linear interpolation within a grid step)."""
    lo = np.floor(ph[:-1])
    hi = np.floor(ph[1:])
    idx = np.nonzero(hi > lo)[0]
    out = []
    for i in idx:
        for level in range(int(lo[i]) + 1, int(hi[i]) + 1):
            f = (level - ph[i]) / (ph[i + 1] - ph[i])
            out.append(t[i] + f * (t[i + 1] - t[i]))
    return np.array(out)


def fire_pulses(world: World, times: np.ndarray, sink: list[float]) -> simpy.Process:
    """A simpy process that fires one event per pulse and records its time."""
    env = world.env

    def proc() -> Generator[simpy.Event, Any, None]:
        for tp in times:
            due = int(math.ceil(tp * 1e9))
            if due > env.now:
                yield env.timeout(due - env.now)
            sink.append(float(tp))

    return env.process(proc())
