"""Dividing head on a turntable with tilt: the case attitude in the lab (report 004, steps 1-12).

Lab frame L = ENU. Turntable azimuth A about L-up (A = 0: spindle's horizontal projection
north, +90 east), tilt E = elevation of the spindle above the horizontal. The spindle axis
is u = (sin A cos E, cos A cos E, sin E). The case rotates with the spindle angle gamma
(right-handed about u, carrying c2 toward c3). Case to lab:

    R_LC = Rz(-A) . Rx(E) . R0 . Rx(gamma) . M

with active rotations Rz, Rx about L-up / L-east, R0 = [north | up | east] (c1, c2, c3 at
A = E = gamma = 0) and M the small mounting rotation of the case on the spindle plate
(sim.esg.case), so c1 = R_LC e1 cones about u as the spindle turns.

Axes move at a slew rate, then settle; the physics sees the new angle only at arrival
(the attitude jumps then, which is what the rotor integration assumes), while the scale
reading follows the slew. Magnitudes:
  * head (Leitz dividing head): slew 3 deg/s, settle 3 s; scale error a seeded sum of four
    harmonics of the scale angle with amplitudes summing to 1.5 arcsec (the report quotes
    two arcsec or better), plus a 0.5 arcsec rms setting error drawn at every arrival;
    reading 5 decimals of a degree.
  * turntable azimuth and tilt: slew 2 deg/s, settle 5 s; 3 arcsec rms setting error per
    axis and arrival; readings 4 decimals.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sim.rng import stream
from sim.units import ARCSEC

R0 = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def rot_x(a: float) -> np.ndarray:
    """Active rotation by a about the first axis."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_z(a: float) -> np.ndarray:
    """Active rotation by a about the third axis."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def spindle_axis(azimuth: float, tilt: float) -> np.ndarray:
    """u in L for table angles in radians."""
    return np.array([math.sin(azimuth) * math.cos(tilt), math.cos(azimuth) * math.cos(tilt),
                     math.sin(tilt)])


def case_to_lab(azimuth: float, tilt: float, gamma: float,
                mounting: np.ndarray | None = None) -> np.ndarray:
    """R_LC = Rz(-A) Rx(E) R0 Rx(gamma) M (radians)."""
    r = rot_z(-azimuth) @ rot_x(tilt) @ R0 @ rot_x(gamma)
    return r if mounting is None else r @ mounting


@dataclass(frozen=True)
class MountSpec:
    """Dividing head and turntable performance."""

    head_slew_deg_s: float = 3.0
    head_settle_s: float = 3.0
    head_scale_error_arcsec: float = 1.5  # sum of the harmonic amplitudes
    head_harmonics: int = 4
    head_setting_arcsec: float = 0.5  # rms, per arrival
    table_slew_deg_s: float = 2.0
    table_settle_s: float = 5.0
    table_setting_arcsec: float = 3.0  # rms per axis, per arrival
    tilt_limit_deg: float = 90.0


@dataclass(frozen=True)
class _Move:
    t0: float
    t_slewed: float
    t_arrive: float
    start_deg: float
    target_deg: float  # end of the path (unwrapped)
    actual_rad: float  # angle in effect from t_arrive


class SlewAxis:
    """One positioning axis: slew, settle, then the commanded angle plus its errors."""

    def __init__(self, name: str, seed: int, setting_sd_arcsec: float, decimals: int,
                 wrap: bool, scale_error: Callable[[float], float] | None = None,
                 initial_deg: float = 0.0) -> None:
        self.name, self.seed, self.decimals, self.wrap = name, seed, decimals, wrap
        self.setting_sd = setting_sd_arcsec * ARCSEC
        self.scale_error = scale_error
        self._count = 0
        self._moves = [_Move(-math.inf, -math.inf, -math.inf, initial_deg, initial_deg,
                             self._actual(initial_deg))]
        self._arrivals = [-math.inf]

    def _actual(self, target_deg: float) -> float:
        """True angle for a commanded angle: scale error plus a fresh setting error."""
        rng = stream(self.seed, "esg", self.name, "setting", self._count)
        self._count += 1
        err = float(rng.normal(0.0, self.setting_sd)) if self.setting_sd > 0 else 0.0
        if self.scale_error is not None:
            err += self.scale_error(target_deg)
        return math.radians(target_deg) + err

    def _norm(self, deg: float) -> float:
        if not self.wrap:
            return deg
        x = deg % 360.0
        return 0.0 if x >= 360.0 else x

    def position_deg(self, now: float) -> float:
        """Where the axis is along its slew (degrees, unrounded, normalised)."""
        m = self._moves[-1]
        if now >= m.t_slewed:
            return self._norm(m.target_deg)
        f = (now - m.t0) / (m.t_slewed - m.t0)
        return self._norm(m.start_deg + f * (m.target_deg - m.start_deg))

    def reading_deg(self, now: float) -> float:
        """The scale reading, rounded to the axis' decimals."""
        return self._norm(round(self.position_deg(now), self.decimals))

    def distance_deg(self, now: float, target_deg: float) -> float:
        """Path length of a move to target_deg from where the axis is now."""
        start = self.position_deg(now)
        delta = target_deg - start
        if self.wrap:
            delta = (delta + 180.0) % 360.0 - 180.0
        return abs(delta)

    def move(self, now: float, target_deg: float, slew_s: float, settle_s: float) -> float:
        """Start a move (a move under way is abandoned where it is); returns arrival time."""
        while len(self._moves) > 1 and self._moves[-1].t_arrive > now:
            self._moves.pop()
            self._arrivals.pop()
        start = self.position_deg(now)
        target = self._norm(target_deg)
        delta = target - start
        if self.wrap:
            delta = (delta + 180.0) % 360.0 - 180.0
        t_arrive = now + slew_s + settle_s
        self._moves.append(_Move(now, now + slew_s, t_arrive, start, start + delta,
                                 self._actual(target)))
        self._arrivals.append(t_arrive)
        return t_arrive

    def moving(self, now: float) -> bool:
        return now < self._moves[-1].t_arrive

    def index(self, t: float) -> int:
        """Index of the move in effect at t."""
        return bisect.bisect_right(self._arrivals, t) - 1

    def actual_rad(self, t: float) -> float:
        """True angle in effect at t (jumps at each arrival)."""
        return self._moves[self.index(t)].actual_rad

    def next_change(self, t: float) -> float:
        i = bisect.bisect_right(self._arrivals, t)
        return self._arrivals[i] if i < len(self._arrivals) else math.inf


def head_scale_error(seed: int, spec: MountSpec) -> Callable[[float], float]:
    """Seeded periodic scale error (rad) of the head versus the scale angle (deg)."""
    rng = stream(seed, "esg", "head", "scale")
    n = spec.head_harmonics
    amp = rng.uniform(0.2, 1.0, n)
    amp *= spec.head_scale_error_arcsec * ARCSEC / amp.sum()
    phase = rng.uniform(0.0, 2.0 * math.pi, n)
    k = np.arange(1, n + 1)

    def err(deg: float) -> float:
        return float(np.sum(amp * np.sin(k * math.radians(deg) + phase)))

    return err


class Mount:
    """Head, turntable azimuth and tilt, with the case mounting: R_LC versus time."""

    def __init__(self, spec: MountSpec, seed: int, mounting: np.ndarray) -> None:
        self.spec, self.mounting = spec, mounting
        # the mounting in effect from each time on (a shim changes it: ``reshim``)
        self._shims: list[tuple[float, np.ndarray]] = [(-math.inf, mounting)]
        self.head = SlewAxis("head", seed, spec.head_setting_arcsec, 5, True,
                             head_scale_error(seed, spec))
        self.azimuth = SlewAxis("azimuth", seed, spec.table_setting_arcsec, 4, True)
        self.tilt = SlewAxis("tilt", seed, spec.table_setting_arcsec, 4, False)
        self._cache: dict[tuple[int, int, int, int], np.ndarray] = {}

    def head_move(self, now: float, gamma_deg: float) -> float:
        s = self.spec
        self._cache.clear()
        dist = self.head.distance_deg(now, gamma_deg)
        return self.head.move(now, gamma_deg, dist / s.head_slew_deg_s, s.head_settle_s)

    def table_move(self, now: float, azimuth_deg: float | None, tilt_deg: float | None
                   ) -> float:
        s = self.spec
        if tilt_deg is not None and abs(tilt_deg) > s.tilt_limit_deg:
            raise ValueError(f"tilt {tilt_deg} deg beyond +-{s.tilt_limit_deg}")
        axes = [(ax, x) for ax, x in ((self.azimuth, azimuth_deg), (self.tilt, tilt_deg))
                if x is not None]
        if not axes:
            return now
        self._cache.clear()
        slew = max(ax.distance_deg(now, x) for ax, x in axes) / s.table_slew_deg_s
        return max(ax.move(now, x, slew, s.table_settle_s) for ax, x in axes)

    def moving_table(self, now: float) -> bool:
        return self.azimuth.moving(now) or self.tilt.moving(now)

    def reshim(self, now: float, mounting: np.ndarray) -> None:
        """The case re-shimmed on the spindle plate: ``mounting`` in effect from ``now``."""
        self._cache.clear()
        self._shims.append((now, mounting))
        self.mounting = mounting

    def mounting_at(self, t: float) -> np.ndarray:
        """The mounting in effect at time t (after the shims and remounts before it)."""
        return self._shims[self._shim_index(t)][1]

    def _shim_index(self, t: float) -> int:
        return bisect.bisect_right([s[0] for s in self._shims], t) - 1

    def angles(self, t: float) -> tuple[float, float, float]:
        """True (A, E, gamma) in radians at t."""
        return self.azimuth.actual_rad(t), self.tilt.actual_rad(t), self.head.actual_rad(t)

    def matrix(self, t: float) -> np.ndarray:
        """R_LC at t (the attitude in effect; piecewise constant)."""
        shim = self._shim_index(t)
        key = (self.azimuth.index(t), self.tilt.index(t), self.head.index(t), shim)
        r = self._cache.get(key)
        if r is None:
            if len(self._cache) > 64:
                self._cache.clear()
            r = case_to_lab(*self.angles(t), self._shims[shim][1])
            self._cache[key] = r
        return r

    def next_change(self, t: float) -> float:
        shim = self._shim_index(t) + 1
        return min(self.azimuth.next_change(t), self.tilt.next_change(t),
                   self.head.next_change(t),
                   self._shims[shim][0] if shim < len(self._shims) else math.inf)
