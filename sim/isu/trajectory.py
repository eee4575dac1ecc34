"""One table axis as a piecewise-analytic angle history.

Segments are either polynomial (p0 + v0 dt + a dt^2 / 2) or a critically damped settle
(pf + d (1 + dt/tau) exp(-dt/tau), which starts at rest). A command at time tc cuts the
history at tc and appends the new plan, so the past is never rewritten.
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from dataclasses import dataclass

import numpy as np

POLY, SETTLE = 0, 1
_FEW = 16  # up to this many instants, evaluate asks _at for each (numpy costs ~30 us a call)


@dataclass(frozen=True)
class Segment:
    ts: float
    kind: int
    p0: float = 0.0
    v0: float = 0.0
    a: float = 0.0
    pf: float = 0.0
    d: float = 0.0
    tau: float = 1.0


class Trajectory:
    """Angle (rad) and rate (rad/s) of one axis as functions of time (s)."""

    def __init__(self, p0: float = 0.0) -> None:
        self.segments: list[Segment] = [Segment(0.0, POLY, p0)]
        # the segments' start times, kinds and parameters as arrays (``_arrays``); the
        # segments are in order of their starts, so a cut or an append keeps a prefix
        self._ts = np.zeros(0)
        self._kind = np.zeros(0, dtype=np.int64)
        self._par = np.zeros((0, 6))
        self._ts_list: list[float] = []
        self._arrays()

    def _arrays(self, keep: int = 0) -> None:
        """The segments' arrays (and start times as a list), of which the first ``keep``
        are still those held: only the segments after them are converted (a day's table
        commands each add a few to hundreds, issue 17)."""
        new = self.segments[keep:]
        self._ts = np.concatenate((self._ts[:keep], np.array([s.ts for s in new], dtype=float)))
        self._kind = np.concatenate((self._kind[:keep],
                                     np.array([s.kind for s in new], dtype=np.int64)))
        self._par = np.concatenate((self._par[:keep], np.array(
            [[s.p0, s.v0, s.a, s.pf, s.d, s.tau] for s in new], dtype=float).reshape(-1, 6)))
        self._ts_list = self._ts_list[:keep] + [s.ts for s in new]

    def _at(self, t: float) -> tuple[float, float]:
        """(angle, rate) at one instant: ``evaluate``'s arithmetic on floats, term by term
        in the same order (the same bits), without numpy's cost per call (most calls ask
        for one instant: a reading, a status, a command's cut)."""
        s = self.segments[max(bisect_right(self._ts_list, t) - 1, 0)]
        dt = t - s.ts
        if s.kind != SETTLE:
            return s.p0 + s.v0 * dt + 0.5 * s.a * dt * dt, s.v0 + s.a * dt
        x = dt / s.tau
        e = float(np.exp(-min(x, 700.0)))  # numpy's exp, as evaluate's
        return s.pf + s.d * (1.0 + x) * e, -s.d * x / s.tau * e

    def state(self, t: float) -> tuple[float, float, float]:
        """(angle, rate, acceleration) at t."""
        p, v = self._at(t)  # evaluate's bits at one instant
        s = self.segments[bisect_right(self._ts_list, t) - 1]
        if s.kind == POLY:
            acc = s.a
        else:
            dt = t - s.ts
            acc = s.d * (dt / s.tau - 1.0) / s.tau**2 * math.exp(-dt / s.tau)
        return p, v, acc

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        if t.size <= _FEW:  # instant by instant: the same bits without numpy's cost per call
            pv = [self._at(x) for x in t.reshape(-1).tolist()]
            return (np.array([p for p, _ in pv]).reshape(t.shape),
                    np.array([v for _, v in pv]).reshape(t.shape))
        i = np.searchsorted(self._ts, t, side="right") - 1
        i = np.maximum(i, 0)
        dt = t - self._ts[i]
        p0, v0, a, pf, d, tau = self._par[i].T
        poly_p = p0 + v0 * dt + 0.5 * a * dt * dt
        poly_v = v0 + a * dt
        x = dt / tau
        e = np.exp(-np.minimum(x, 700.0))
        set_p = pf + d * (1.0 + x) * e
        set_v = -d * x / tau * e
        settle = self._kind[i] == SETTLE
        return np.where(settle, set_p, poly_p), np.where(settle, set_v, poly_v)

    def breakpoints(self, t0: float, t1: float) -> list[float]:
        """Segment starts strictly inside (t0, t1)."""
        ts = self._ts_list
        return [float(x) for x in ts[bisect_right(ts, t0):bisect_left(ts, t1)]]

    def cut(self, tc: float) -> tuple[float, float]:
        """Drop every segment starting after tc; return (angle, rate) at tc."""
        p, v, _ = self.state(tc)
        self.segments = self.segments[:bisect_right(self._ts_list, tc)]
        self._arrays(len(self.segments))  # the arrays hold what is held: a second cut reads them
        return p, v

    def append(self, segs: list[Segment]) -> None:
        # A new segment at the same start time replaces the old one. The segments held are
        # a prefix of those the arrays hold (a cut keeps one): those kept are one too.
        keep = len(self.segments)
        if segs:
            keep = min(keep, bisect_left(self._ts_list, segs[0].ts))
            self.segments = self.segments[:keep] + segs
        self._arrays(keep)

    def last_change(self) -> float:
        return float(self._ts[-1])


def plan_stop(tc: float, p: float, v: float, amax: float) -> tuple[list[Segment], float, float]:
    """Decelerate from (p, v) to rest; returns segments, stop time and stop angle."""
    if v == 0.0:
        return [Segment(tc, POLY, p)], tc, p
    a = -math.copysign(amax, v)
    dur = abs(v) / amax
    p_stop = p + v * dur + 0.5 * a * dur * dur
    return [Segment(tc, POLY, p, v, a), Segment(tc + dur, POLY, p_stop)], tc + dur, p_stop


def plan_move(
    tc: float, p0: float, p1: float, vmax: float, amax: float, overshoot: float, tau: float
) -> tuple[list[Segment], float]:
    """Trapezoidal slew from rest at p0 to p1 + overshoot, then settle on p1.

    Returns the segments and the time the residual falls below 0.01 of the overshoot.
    """
    target = p1 + overshoot
    d = target - p0
    s = 1.0 if d >= 0 else -1.0
    dist = abs(d)
    segs: list[Segment] = []
    t = tc
    if dist > 0:
        if dist >= vmax * vmax / amax:
            ta, vp = vmax / amax, vmax
            tcr = (dist - vmax * vmax / amax) / vmax
        else:
            ta = math.sqrt(dist / amax)
            vp, tcr = amax * ta, 0.0
        x_a = 0.5 * amax * ta * ta
        segs.append(Segment(t, POLY, p0, 0.0, s * amax))
        t += ta
        if tcr > 0:
            segs.append(Segment(t, POLY, p0 + s * x_a, s * vp, 0.0))
            t += tcr
        segs.append(Segment(t, POLY, target - s * x_a, s * vp, -s * amax))
        t += ta
    segs.append(Segment(t, SETTLE, pf=p1, d=overshoot, tau=tau))
    # (1 + x) e^-x < 0.01 for x > 6.64
    return segs, t + 6.64 * tau


def plan_rate(
    tc: float, p: float, v: float, v1: float, accel: float
) -> tuple[list[Segment], float]:
    """Ramp the rate from v to v1 at |accel|, then hold v1; returns segments and ramp end."""
    if v1 == v:
        return [Segment(tc, POLY, p, v, 0.0)], tc
    a = math.copysign(accel, v1 - v)
    dur = abs(v1 - v) / accel
    p_end = p + v * dur + 0.5 * a * dur * dur
    return [Segment(tc, POLY, p, v, a), Segment(tc + dur, POLY, p_end, v1, 0.0)], tc + dur
