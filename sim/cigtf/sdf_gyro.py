"""SDF torque-to-balance gyro of report 001 Appendix I, with time behaviour.

Drift coefficients are rad/s per g^k with accelerations in g along O, S, I; S_T is rad/s
per ampere; the current is in amperes. Gravity is +1 g along Earth X (up), as Appendix I.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.rng import stream
from sim.units import EARTH_RATE


@dataclass(frozen=True)
class DriftModel:
    """Appendix I coefficients and the torquer scale factor."""

    s_t: float
    d_f: float = 0.0
    d_i: float = 0.0
    d_o: float = 0.0
    d_s: float = 0.0
    d_ii: float = 0.0
    d_ss: float = 0.0
    d_io: float = 0.0
    d_is: float = 0.0
    d_os: float = 0.0
    # magnetic drift: rad/s per gauss of the Earth's field along I, at the rotor voltage the
    # world runs (the spin motor's stray moment scales with its excitation; not Appendix I)
    d_m: float = 0.0


# The site's magnetic field in the Earth frame (X up, Y north, Z west), gauss: horizontal
# 0.26 G at a declination of 12 deg east, 0.45 G downward (our figures, near Holloman AFB;
# report 001 gives none). Its west component, along I in orientations 1 and 3, survives the
# four-orientation sum as an azimuth error.
EARTH_FIELD_GAUSS = np.array([-0.45, 0.26 * math.cos(math.radians(12.0)),
                              -0.26 * math.sin(math.radians(12.0))])


def earth_rate_vector(latitude: float) -> np.ndarray:
    """Earth rate in the Earth frame (X up, Y north, Z west), rad/s."""
    return EARTH_RATE * np.array([math.sin(latitude), math.cos(latitude), 0.0])


def steady_current(m: DriftModel, q_ge: np.ndarray, latitude: float, d_f_extra: float = 0.0
                   ) -> float:
    """Torque-to-balance current from the Appendix I model at attitude Q_GE."""
    a_o, a_s, a_i = q_ge @ np.array([1.0, 0.0, 0.0])
    w_i = float((q_ge @ earth_rate_vector(latitude))[2])
    rate = (m.d_f + d_f_extra + m.d_i * a_i + m.d_o * a_o + m.d_s * a_s + m.d_ii * a_i**2
            + m.d_ss * a_s**2 + m.d_io * a_i * a_o + m.d_is * a_i * a_s + m.d_os * a_o * a_s
            + w_i)
    if m.d_m:
        rate += m.d_m * float((q_ge @ EARTH_FIELD_GAUSS)[2])
    return rate / m.s_t


@dataclass(frozen=True)
class Dynamics:
    """Settling, warm-up and instabilities (rates rad/s, times s)."""

    settle_tau: float = 20.0
    warmup_amplitude: float = 0.0
    warmup_tau: float = 1800.0
    drift_walk: float = 0.0  # rad/s per sqrt(s): random walk of D_F while running
    turn_on_sd: float = 0.0  # rad/s: D_F shift drawn at each turn-on
    knot_spacing: float = 600.0


class SdfGyro:
    """Current versus time: steady value plus settling, warm-up and drift of D_F."""

    def __init__(self, model: DriftModel, latitude: float, dyn: Dynamics, seed: int) -> None:
        self.model, self.latitude, self.dyn, self.seed = model, latitude, dyn, seed
        self.turn_ons = 0
        self.on_since: float | None = None
        self._shift = 0.0
        self._knots = np.zeros(1)
        self._knot_x = np.arange(1)
        self._attitude: tuple[float, float, float] = (0.0, 0.0, 0.0)  # t, from, to

    def power_on(self, t: float, q_ge: np.ndarray) -> None:
        """Turn on at t: a new turn-on shift and a fresh walk of D_F."""
        self.turn_ons += 1
        self.on_since = t
        rng = stream(self.seed, "sdf_gyro", "turn_on", self.turn_ons)
        self._shift = float(rng.normal(0.0, self.dyn.turn_on_sd))
        self._knots = np.zeros(1)
        self._knot_x = np.arange(1)
        i = self._steady(q_ge)
        self._attitude = (t, i, i)

    def power_off(self) -> None:
        """Turn off; the current reads zero."""
        self.on_since = None

    def moved(self, t: float, q_ge: np.ndarray) -> None:
        """The fixture finished a move at t; the loop settles from the old current."""
        old = self._settling_part(t) + self._attitude[2]
        self._attitude = (t, old, self._steady(q_ge))

    def _steady(self, q_ge: np.ndarray) -> float:
        return steady_current(self.model, q_ge, self.latitude)

    def _settling_part(self, t: float) -> float:
        t0, i_from, i_to = self._attitude
        return (i_from - i_to) * math.exp(-max(t - t0, 0.0) / self.dyn.settle_tau)

    def _walk(self, since_on: float) -> float:
        """D_F random walk at a time since turn-on, linear between seeded knots."""
        k = since_on / self.dyn.knot_spacing
        need = int(k) + 2
        if self._knots.size < need:
            sd = self.dyn.drift_walk * math.sqrt(self.dyn.knot_spacing)
            steps = [stream(self.seed, "sdf_gyro", "walk", self.turn_ons, n).normal(0.0, sd)
                     for n in range(self._knots.size, need)]
            self._knots = np.concatenate([self._knots, self._knots[-1] + np.cumsum(steps)])
        if self._knot_x.size != self._knots.size:  # the knots' abscissae, made once per growth
            self._knot_x = np.arange(self._knots.size)
        return float(np.interp(k, self._knot_x, self._knots))

    def extra_drift(self, t: float) -> float:
        """D_F change now: turn-on shift, warm-up transient and walk, rad/s."""
        if self.on_since is None:
            return 0.0
        s = t - self.on_since
        warm = self.dyn.warmup_amplitude * math.exp(-s / self.dyn.warmup_tau)
        return self._shift + warm + self._walk(s)

    def _walks(self, since_on: np.ndarray) -> np.ndarray:
        """:meth:`_walk` at many times since turn-on in one evaluation (same knots)."""
        self._walk(float(since_on.max()))  # grows the knots as far as the latest time needs
        return np.interp(since_on / self.dyn.knot_spacing, self._knot_x, self._knots)

    def currents(self, t: np.ndarray) -> np.ndarray:
        """:meth:`current` at each of the times t (s), in one evaluation, amperes."""
        if self.on_since is None:
            return np.zeros_like(t)
        t0, i_from, i_to = self._attitude
        settling = (i_from - i_to) * np.exp(-np.maximum(t - t0, 0.0) / self.dyn.settle_tau)
        s = t - self.on_since
        warm = self.dyn.warmup_amplitude * np.exp(-s / self.dyn.warmup_tau)
        extra = self._shift + warm + self._walks(s)
        return i_to + settling + extra / self.model.s_t

    def current(self, t: float) -> float:
        """Torquer current at time t (s), amperes; zero when off."""
        if self.on_since is None:
            return 0.0
        return self._attitude[2] + self._settling_part(t) + self.extra_drift(t) / self.model.s_t
