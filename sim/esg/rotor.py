"""Spin speed and spin-axis motion of the ESG rotor in the lab frame (report 004, sec. 3).

Lab frame L = ENU (docs/esg.md). In inertial space the spin axis s moves only
under torque; seen from the Earth-fixed lab it also turns against the Earth:

    ds/dt = s x (k down + Omega_E) + e_electric + damping,   k = (m g delta) / (I w).

* Axial mass unbalance: torque (m g delta)(s x down), 11 dyne-cm on this gyro (the
  specification was 0.2); with I = 114 g cm^2 and w = 2 pi 250 rad/s, k = 12.7 deg/h.
  The drift-free direction in the lab is unit(Omega_E + k down), in the north-south
  vertical plane, as used by the report's drift cancellation (procedure step 3).
* Electric torque: a smooth tangent field fixed in the case frame C,
  e = s_c x grad V(s_c) with V a seeded quadratic plus cubic-symmetric quartic form,
  scaled to an rms of 0.2 deg/h over the sphere at 250 rps (a fixed torque, so the
  drift grows as the rotor runs down); it changes when the case is turned.
* Damping (console DAMP ON, rotor spinning): s precesses toward the damping-coil axis c1
  as (c1 - (c1.s) s) / tau_d, tau_d = 60 s.
* Speed: the console's spin-up is a linear ramp at spin_rps / spinup_s (250 rps in
  1800 s); at full speed the drive stops and the rotor runs down exponentially with
  tau = 88 h (250 rps at the start, about 244 rps 2.15 h later as in Appendix A).
  SPIN OFF brakes linearly at the spin-up rate. The spin coils' torque I dw/dt acts
  along their axis, which is the damping-coil axis c1, so while they drive it also
  turns s: ds/dt += (dw/dt / w)(c1 - (c1.s) s) (toward c1 spinning up, away braking).
  Below free_rps = 10 rps the rotor is no gyro to speak of and the axis is held on c1,
  so a rotor at rest or just starting follows the case.

Integration: fixed-step RK4 (step_s, 5 s) with renormalisation, done lazily up to the
time asked for, on a grid that restarts at every break point (case arrival, damping
switch, spin-profile change), so the inputs are constant over each step. The case
attitude is piecewise constant: a move takes effect at its arrival time. Every grid
point is kept, and a query between grid points integrates one partial step from the
grid point before it, so the answer does not depend on the order of the queries.
The grid never runs past the time asked for, and the world only asks for t <= now.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from sim.rng import stream
from sim.units import DEG_PER_HR, EARTH_RATE, HOUR

Vec = tuple[float, float, float]
# The report's laboratory (Honeywell Aerospace Division, Minneapolis): the one place the ESG
# laboratory's default latitude is written.
LAB_LATITUDE_DEG = 44.98


@dataclass(frozen=True)
class RotorSpec:
    """Rotor, unbalance, electric torque, damping and the console's spin profile, and the
    laboratory's latitude (the Earth rate the spin axis turns against in the lab)."""

    latitude_deg: float = LAB_LATITUDE_DEG
    spin_rps: float = 250.0
    spinup_s: float = 1800.0
    rundown_tau_h: float = 88.0  # math.inf: no rundown
    inertia_g_cm2: float = 114.0
    unbalance_dyne_cm: float = 11.0
    electric_deg_h: float = 0.2
    damping_tau_s: float = 60.0
    step_s: float = 5.0
    free_rps: float = 10.0  # below this the spin coils' field holds the axis on c1


class AttitudeSource(Protocol):
    """Case attitude R_LC (case to lab) as a piecewise-constant function of time."""

    def matrix(self, t: float) -> np.ndarray: ...

    def next_change(self, t: float) -> float: ...


def _cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _unit(a: npt.ArrayLike) -> np.ndarray:
    a = np.asarray(a, float)
    return a / np.linalg.norm(a)


# ----- spin speed -----
@dataclass(frozen=True)
class _Segment:
    t0: float
    kind: str  # "stopped" | "ramp" | "brake" | "run"
    w0: float  # rps at t0
    rev0: float  # revolutions turned before t0


class SpinProfile:
    """Spin speed (rps) and revolutions turned versus time, piecewise analytic."""

    def __init__(self, spin_rps: float, spinup_s: float, tau_s: float, free_rps: float) -> None:
        self.target, self.rate, self.tau = spin_rps, spin_rps / spinup_s, tau_s
        self.free_rps = free_rps
        self._segs = [_Segment(-math.inf, "stopped", 0.0, 0.0)]
        self._t0s = [-math.inf]

    def _seg(self, t: float) -> _Segment:
        return self._segs[bisect.bisect_right(self._t0s, t) - 1]

    def _speed_in(self, g: _Segment, t: float) -> float:
        dt = t - g.t0
        if g.kind == "ramp":
            return g.w0 + self.rate * dt
        if g.kind == "brake":
            return max(g.w0 - self.rate * dt, 0.0)
        if g.kind == "run":
            return g.w0 * math.exp(-dt / self.tau)
        return 0.0

    def _revs_in(self, g: _Segment, t: float) -> float:
        dt = t - g.t0
        if g.kind == "ramp":
            return g.rev0 + g.w0 * dt + 0.5 * self.rate * dt * dt
        if g.kind == "brake":
            dt = min(dt, g.w0 / self.rate)
            return g.rev0 + g.w0 * dt - 0.5 * self.rate * dt * dt
        if g.kind == "run":
            if math.isinf(self.tau):
                return g.rev0 + g.w0 * dt
            return g.rev0 - g.w0 * self.tau * math.expm1(-dt / self.tau)
        return g.rev0

    def speed(self, t: float) -> float:
        """Spin speed at t, rps."""
        return self._speed_in(self._seg(t), t)

    def revolutions(self, t: float) -> float:
        """Revolutions turned since the first spin-up."""
        return self._revs_in(self._seg(t), t)

    def kind(self, t: float) -> str:
        return self._seg(t).kind

    def drive(self, t: float) -> float:
        """Rate (rps/s) the console's spin coils impose at t: + spin-up, - braking, 0 off."""
        kind = self._seg(t).kind
        return self.rate if kind == "ramp" else -self.rate if kind == "brake" else 0.0

    def _restart(self, t: float) -> tuple[float, float]:
        g = self._seg(t)
        w, rev = self._speed_in(g, t), self._revs_in(g, t)
        while self._t0s[-1] >= t and len(self._segs) > 1:
            self._segs.pop()
            self._t0s.pop()
        return w, rev

    def _append(self, t0: float, kind: str, w0: float, rev0: float) -> None:
        self._segs.append(_Segment(t0, kind, w0, rev0))
        self._t0s.append(t0)

    def spin_up(self, t: float) -> None:
        """Drive to the target speed from whatever speed the rotor has at t."""
        w, rev = self._restart(t)
        if w < self.target:
            self._append(t, "ramp", w, rev)
            if w < self.free_rps < self.target:  # a break point where the axis is let go
                tc = t + (self.free_rps - w) / self.rate
                self._append(tc, "ramp", self.free_rps, self._revs_in(self._segs[-1], tc))
            te = t + (self.target - w) / self.rate
            self._append(te, "run", self.target, self._revs_in(self._segs[-1], te))
        else:
            self._append(t, "run", w, rev)

    def spin_off(self, t: float) -> None:
        """Brake to rest at the spin-up rate."""
        w, rev = self._restart(t)
        if w > 0.0:
            self._append(t, "brake", w, rev)
            if w > self.free_rps:  # a break point where the coils take the axis over
                tc = t + (w - self.free_rps) / self.rate
                self._append(tc, "brake", self.free_rps, self._revs_in(self._segs[-1], tc))
            te = t + w / self.rate
            self._append(te, "stopped", 0.0, self._revs_in(self._segs[-1], te))
        else:
            self._append(t, "stopped", 0.0, rev)

    def next_change(self, t: float) -> float:
        i = bisect.bisect_right(self._t0s, t)
        return self._t0s[i] if i < len(self._t0s) else math.inf


# ----- electric torque -----
class ElectricField:
    """Seeded electric-torque drift in the case frame: s x grad V(s), rms `rate` rad/s."""

    def __init__(self, seed: int, rate: float) -> None:
        rng = stream(seed, "esg", "rotor", "electric")
        q = rng.normal(0.0, 1.0, (3, 3))
        self.q = 0.5 * (q + q.T)
        self.a = float(rng.normal(0.0, 1.0))
        self._qt = tuple(tuple(float(x) for x in row) for row in self.q)  # floats: no numpy
        pts = self._fibonacci(400)
        rms = math.sqrt(np.mean([sum(x * x for x in self._raw(tuple(p))) for p in pts]))
        self.scale = rate / rms if rms > 0 else 0.0

    @staticmethod
    def _fibonacci(n: int) -> np.ndarray:
        i = np.arange(n) + 0.5
        z = 1.0 - 2.0 * i / n
        r = np.sqrt(1.0 - z * z)
        ph = math.pi * (1.0 + math.sqrt(5.0)) * i
        return np.column_stack([r * np.cos(ph), r * np.sin(ph), z])

    def _raw(self, s: Vec) -> Vec:
        (q0, q1, q2), a4 = self._qt, 4.0 * self.a  # written out per axis, floats: no
        # generator and no numpy scalar per call
        grad = (2.0 * (q0[0] * s[0] + q0[1] * s[1] + q0[2] * s[2]) + a4 * s[0] ** 3,
                2.0 * (q1[0] * s[0] + q1[1] * s[1] + q1[2] * s[2]) + a4 * s[1] ** 3,
                2.0 * (q2[0] * s[0] + q2[1] * s[1] + q2[2] * s[2]) + a4 * s[2] ** 3)
        return _cross(s, grad)

    def drift(self, s: Vec) -> Vec:
        """ds/dt (rad/s) in the case frame for the case-frame spin axis s."""
        e = self._raw(s)
        return (self.scale * e[0], self.scale * e[1], self.scale * e[2])


# ----- the rotor -----
class Rotor:
    """Spin axis (unit vector in L) and speed versus time under the console's commands."""

    def __init__(self, spec: RotorSpec, seed: int, attitude: AttitudeSource) -> None:
        self.spec, self.att = spec, attitude
        self.profile = SpinProfile(spec.spin_rps, spec.spinup_s, spec.rundown_tau_h * HOUR,
                                   spec.free_rps)
        lat = math.radians(spec.latitude_deg)
        self.omega: Vec = (0.0, EARTH_RATE * math.cos(lat), EARTH_RATE * math.sin(lat))
        self.unbalance = spec.unbalance_dyne_cm / spec.inertia_g_cm2  # (m g delta)/I, 1/s^2
        self.field = ElectricField(seed, spec.electric_deg_h * DEG_PER_HR)
        self._damp_t: list[float] = [-math.inf]
        self._damp_on: list[bool] = [False]
        self._ts: list[float] = [0.0]
        self._ss: list[np.ndarray] = [self._c1(0.0)]

    # ----- console -----
    def spin_up(self, t: float) -> None:
        self._advance(t)
        self.profile.spin_up(t)

    def spin_off(self, t: float) -> None:
        self._advance(t)
        self.profile.spin_off(t)

    def set_damping(self, t: float, on: bool) -> None:
        self._advance(t)
        if self.damping(t) == bool(on):
            return
        if self._damp_t[-1] == t:
            self._damp_t.pop()
            self._damp_on.pop()
        else:
            self._damp_t.append(t)
            self._damp_on.append(bool(on))

    def damping(self, t: float) -> bool:
        return self._damp_on[bisect.bisect_right(self._damp_t, t) - 1]

    def spin_rps(self, t: float) -> float:
        return self.profile.speed(t)

    def free(self, t: float) -> bool:
        """Fast enough to be a gyro: the axis obeys the dynamics (else it is held on c1)."""
        return self.profile.speed(t) >= self.spec.free_rps

    def k(self, t: float) -> float:
        """Unbalance drift rate (m g delta)/H, rad/s."""
        return self.unbalance / (2.0 * math.pi * self.profile.speed(t))

    # ----- dynamics -----
    def _c1(self, t: float) -> np.ndarray:
        return np.array(self.att.matrix(t)[:, 0], float)

    def _next_break(self, t: float) -> float:
        i = bisect.bisect_right(self._damp_t, t)
        td = self._damp_t[i] if i < len(self._damp_t) else math.inf
        return min(self.att.next_change(t), self.profile.next_change(t), td)

    def _deriv(self, t: float, s: Vec, r: tuple, damp: bool, drive: float) -> Vec:
        f = self.profile.speed(t)
        k = self.unbalance / (2.0 * math.pi * f)
        w = (self.omega[0], self.omega[1], self.omega[2] - k)
        d = _cross(s, w)
        if self.field.scale:
            r0, r1, r2 = r  # the products written out per axis (the same order of terms)
            sc = (r0[0] * s[0] + r1[0] * s[1] + r2[0] * s[2],
                  r0[1] * s[0] + r1[1] * s[1] + r2[1] * s[2],
                  r0[2] * s[0] + r1[2] * s[1] + r2[2] * s[2])
            e = self.field.drift(sc)
            g = self.spec.spin_rps / f  # a fixed torque: drift inversely as the speed
            d = (d[0] + g * (r0[0] * e[0] + r0[1] * e[1] + r0[2] * e[2]),
                 d[1] + g * (r1[0] * e[0] + r1[1] * e[1] + r1[2] * e[2]),
                 d[2] + g * (r2[0] * e[0] + r2[1] * e[1] + r2[2] * e[2]))
        g = (1.0 / self.spec.damping_tau_s if damp else 0.0) + drive / f
        if g:
            c1 = (r[0][0], r[1][0], r[2][0])
            dot = c1[0] * s[0] + c1[1] * s[1] + c1[2] * s[2]
            d = (d[0] + g * (c1[0] - dot * s[0]), d[1] + g * (c1[1] - dot * s[1]),
                 d[2] + g * (c1[2] - dot * s[2]))
        return d

    def _step(self, t0: float, s0: np.ndarray, t1: float) -> np.ndarray:
        """State at t1 from s0 at t0; no break point lies strictly between them."""
        mid = 0.5 * (t0 + t1)
        if not self.free(mid):
            return self._c1(mid)
        r = tuple(tuple(float(x) for x in row) for row in self.att.matrix(mid))
        damp = self.damping(mid)
        drive = self.profile.drive(mid)
        h = t1 - t0
        s = (float(s0[0]), float(s0[1]), float(s0[2]))

        def add(a: Vec, b: Vec, f: float) -> Vec:
            return (a[0] + f * b[0], a[1] + f * b[1], a[2] + f * b[2])

        k1 = self._deriv(t0, s, r, damp, drive)
        k2 = self._deriv(mid, add(s, k1, 0.5 * h), r, damp, drive)
        k3 = self._deriv(mid, add(s, k2, 0.5 * h), r, damp, drive)
        k4 = self._deriv(t1, add(s, k3, h), r, damp, drive)
        h6 = h / 6.0
        out = [s[0] + h6 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
               s[1] + h6 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
               s[2] + h6 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])]
        return _unit(out)

    def _advance(self, t: float) -> None:
        """Extend the grid to the last grid point at or before t."""
        h = self.spec.step_s
        while True:
            tc = self._ts[-1]
            tn = min(tc + h, self._next_break(tc))
            if tn > t:
                return
            self._ss.append(self._step(tc, self._ss[-1], tn))
            self._ts.append(tn)

    def axis_lab(self, t: float) -> np.ndarray:
        """Unit spin axis in L at time t (t must not be in the world's future)."""
        if not self.free(t):
            return self._c1(t)
        self._advance(t)
        i = bisect.bisect_right(self._ts, t) - 1
        if self._ts[i] == t:
            return self._ss[i].copy()
        return self._step(self._ts[i], self._ss[i], t)

    def place(self, t: float, s_lab: npt.ArrayLike) -> None:
        """Put the spin axis at s_lab at time t = now (a test and set-up hook)."""
        self._advance(t)
        if self._ts[-1] < t:
            self._ss.append(self._step(self._ts[-1], self._ss[-1], t))
            self._ts.append(t)
        self._ss[-1] = _unit(s_lab)
