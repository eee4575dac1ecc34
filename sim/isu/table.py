"""Four-axis test table of report 000: trunnion phi1, rotary phi2, outer phi3, inner phi4.

Frame chain (Chart I-4): T^BE = T^BI T^IO T^OR T^RT T^TF T^FE. Imperfections: each
resolver reads the true angle plus a cyclic error (about 1 arcsec), each setting lands
within a small noise of the commanded reading, each gimbal junction carries a small fixed
non-orthogonality, and the base is tilted statically and by the pier (sim.isu.environment).
"""

from __future__ import annotations

import math
from typing import overload

import numpy as np

from sim import units
from sim.frames import gimbal, gimbal_at, transform_of_rotated, transform_of_rotated_at
from sim.isu.environment import Environment
from sim.isu.params import TableParams
from sim.isu.trajectory import Trajectory, plan_move, plan_rate, plan_stop
from sim.rng import stream

AXES = (1, 2, 3, 4)
CONTINUOUS = (2, 3, 4)


class TableError(ValueError):
    """A command the table cannot carry out (out of range, too fast)."""


class FourAxisTable:
    """Kinematics and servo behaviour of the table; angles in rad, SI throughout."""

    def __init__(self, p: TableParams, env: Environment, seed: int) -> None:
        self.p = p
        self.env = env
        self.seed = seed
        rng = stream(seed, "table", "imperfections")
        amp = units.arcsec(p.resolver_error_arcsec)
        # Cyclic resolver error per axis: first and second harmonic with seeded phases.
        self._res_err = {k: (amp * 0.8, amp * 0.6, *rng.uniform(0, 2 * math.pi, 2)) for k in AXES}
        no = units.arcsec(p.nonorthogonality_arcsec)
        # Small fixed rotations at the junctions T->R, R->O, O->I (rotation vectors).
        self.nonortho = {k: rng.normal(0.0, no, 3) for k in ("RT", "OR", "IO")}
        self._n = {k: transform_of_rotated(v) for k, v in self.nonortho.items()}
        tilt_e, tilt_n = (units.arcsec(x) for x in p.base_tilt_arcsec)
        self.base_rotation = np.array([units.arcsec(p.base_azimuth_arcsec), tilt_e, tilt_n])
        self.axes = {k: Trajectory(0.0) for k in AXES}
        self._settled_at = {k: 0.0 for k in AXES}
        self._mode = {k: "HOLD" for k in AXES}
        self._setting_count = 0
        self.pulses_per_rev = 1
        self.rotation_output = True  # False: the rotary pulse output is dead (a fault)

    # ----- resolvers -----
    @overload
    def resolver_error(self, axis: int, p: float) -> float: ...
    @overload
    def resolver_error(self, axis: int, p: np.ndarray) -> np.ndarray: ...
    def resolver_error(self, axis: int, p: float | np.ndarray) -> float | np.ndarray:
        """Resolver reading minus true angle (rad) of ``axis`` at true angle(s) p."""
        a1, a2, f1, f2 = self._res_err[axis]
        return a1 * np.sin(p + f1) + a2 * np.sin(2 * p + f2)

    def resolver(self, axis: int, t: float) -> float:
        """Resolver reading (rad, not wrapped, quantized to the resolver resolution)."""
        p, _ = self.axes[axis].evaluate(np.array([t]))
        r = float(p[0] + self.resolver_error(axis, p[0]))
        q = units.arcsec(self.p.resolver_resolution_arcsec)
        return round(r / q) * q

    def _true_target(self, axis: int, reading: float) -> float:
        """True angle at which the servo leaves the resolver reading near ``reading``."""
        rng = stream(self.seed, "table", "setting", self._setting_count)
        self._setting_count += 1
        noise = rng.normal(0.0, units.arcsec(self.p.setting_noise_arcsec))
        p = reading + noise
        for _ in range(3):  # solve p + e(p) = reading + noise
            p = reading + noise - float(self.resolver_error(axis, p))
        return p

    # ----- commands (return the time the axis is settled / at rate) -----
    def check_move(self, axis: int, angle: float) -> None:
        """Refuse a position the axis cannot reach (the trunnion's range)."""
        if axis == 1:
            lo, hi = (math.radians(x) for x in self.p.trunnion_range_deg)
            if not lo <= angle <= hi:
                raise TableError(f"axis 1 angle {math.degrees(angle):.4f} deg out of range")

    def check_rate(self, axis: int, rate: float, accel: float | None = None) -> float:
        """Refuse a rate or acceleration beyond the limits; the acceleration to use (rad/s^2)."""
        if axis not in CONTINUOUS:
            raise TableError(f"axis {axis} cannot rotate continuously")
        if abs(rate) > math.radians(self.p.max_rate_deg_s) + 1e-12:
            raise TableError(
                f"rate {math.degrees(rate):.4f} deg/s exceeds {self.p.max_rate_deg_s} deg/s"
            )
        amax = math.radians(self.p.max_accel_deg_s2)
        acc = amax if accel is None else abs(accel)
        if acc <= 0 or acc > amax + 1e-12:
            raise TableError(
                f"acceleration {math.degrees(acc):.4f} deg/s^2 outside (0, "
                f"{self.p.max_accel_deg_s2}] deg/s^2"
            )
        return acc

    def move(self, axis: int, angle: float, t: float) -> float:
        self.check_move(axis, angle)
        tr = self.axes[axis]
        p, v = tr.cut(t)
        vmax = math.radians(self.p.slew_rate_deg_s)
        amax = math.radians(self.p.slew_accel_deg_s2)
        segs, t_stop, p_stop = plan_stop(t, p, v, amax)
        reading = angle
        if axis in CONTINUOUS:  # shortest way round from where the axis stops
            cur = p_stop + float(self.resolver_error(axis, p_stop))
            reading = cur + (angle - cur + math.pi) % (2 * math.pi) - math.pi
        target = self._true_target(axis, reading)
        rng = stream(self.seed, "table", "overshoot", self._setting_count)
        over = units.arcsec(self.p.overshoot_arcsec) * float(rng.uniform(-1.0, 1.0))
        mv, t_done = plan_move(t_stop, p_stop, target, vmax, amax, over, self.p.settle_tau_s)
        tr.append(segs[:-1] + mv if len(segs) > 1 else mv)
        self._mode[axis] = "MOVE"
        self._settled_at[axis] = t_done
        return t_done

    def rotate(self, axis: int, rate: float, t: float, accel: float | None = None) -> float:
        acc = self.check_rate(axis, rate, accel)
        tr = self.axes[axis]
        p, v = tr.cut(t)
        segs, t_done = plan_rate(t, p, v, rate, acc)
        tr.append(segs)
        self._mode[axis] = "RATE" if rate != 0 else "HOLD"
        self._settled_at[axis] = t_done
        return t_done

    def stop(self, axis: int, t: float) -> float:
        tr = self.axes[axis]
        p, v = tr.cut(t)
        segs, t_stop, _ = plan_stop(t, p, v, math.radians(self.p.slew_accel_deg_s2))
        tr.append(segs)
        self._mode[axis] = "HOLD"
        self._settled_at[axis] = t_stop
        return t_stop

    def status(self, axis: int, t: float) -> str:
        """HOLD (settled), MOVING, SETTLING, ACCEL (rate ramp) or ROTATING."""
        if self._mode[axis] == "RATE":
            return "ACCEL" if t < self._settled_at[axis] else "ROTATING"
        if t >= self._settled_at[axis]:
            return "HOLD"
        _, v, _ = self.axes[axis].state(t)
        return "MOVING" if abs(v) > 1e-7 else "SETTLING"

    def breakpoints(self, t0: float, t1: float) -> list[float]:
        out: set[float] = set()
        for tr in self.axes.values():
            out.update(tr.breakpoints(t0, t1))
        return sorted(out)

    def abs_rate(self, t: np.ndarray) -> np.ndarray:
        """Largest |axis rate| at each time (rad/s)."""
        return np.max([np.abs(tr.evaluate(t)[1]) for tr in self.axes.values()], axis=0)

    def last_change(self) -> float:
        return max(tr.last_change() for tr in self.axes.values())

    # ----- kinematics -----
    def frames(self, t: float | np.ndarray) -> dict[str, np.ndarray]:
        """Gimbal transforms and axis angles/rates at times t (arrays, leading dim N)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self._frames_at(t) if t.shape == (1,) else self._frames_of(t)

    def _frames_of(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """``frames`` at the times t by array arithmetic (any number of them)."""
        ang, rate = {}, {}
        for k in AXES:
            ang[k], rate[k] = self.axes[k].evaluate(t)
        eps, eps_rate = self.env.tilt_and_rate(t)
        eps = eps + self.base_rotation
        return {
            "t_io": gimbal(ang[4]) @ self._n["IO"],
            "t_or": gimbal(ang[3]) @ self._n["OR"],
            "t_rt": gimbal(ang[2]) @ self._n["RT"],
            "t_tf": gimbal(ang[1]),
            "t_fe": transform_of_rotated(eps),
            "eps_rate": eps_rate,
            "angles": ang,
            "rates": rate,
        }

    def _frames_at(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """``frames`` at one instant (``t`` of shape (1,)): each matrix made as a (3, 3) by
        sim.frames' one-instant forms, with the bits ``_frames_of`` gives that instant (a
        reading of the bubble levels or an autocollimator: 465 a day, half the time, issue
        17)."""
        at = {k: self.axes[k]._at(float(t[0])) for k in AXES}  # evaluate's few-instant path
        eps, eps_rate = self.env.tilt_and_rate(t)
        eps = eps + self.base_rotation
        return {
            "t_io": (gimbal_at(at[4][0]) @ self._n["IO"])[None],
            "t_or": (gimbal_at(at[3][0]) @ self._n["OR"])[None],
            "t_rt": (gimbal_at(at[2][0]) @ self._n["RT"])[None],
            "t_tf": gimbal_at(at[1][0])[None],
            "t_fe": transform_of_rotated_at(eps[0])[None],
            "eps_rate": eps_rate,
            "angles": {k: np.array([p]) for k, (p, _) in at.items()},
            "rates": {k: np.array([v]) for k, (_, v) in at.items()},
        }

    def rotation_phase(self, t: float | np.ndarray) -> np.ndarray:
        """Phase (cycles) of the rotary-axis pulse output: one pulse per 1/n turn of resolver 2."""
        if isinstance(t, float) and self.rotation_output:  # one instant (a counter's edge
            q, _ = self.axes[2]._at(t)  # search): evaluate's bits without its arrays
            return np.asarray((q + self.resolver_error(2, q)) * self.pulses_per_rev
                              / (2 * math.pi))
        t = np.asarray(t, dtype=float)
        if not self.rotation_output:  # no pulse output: no trajectory to evaluate
            return np.zeros(t.shape)
        p, _ = self.axes[2].evaluate(t)
        r = p + self.resolver_error(2, p)
        return r * self.pulses_per_rev / (2 * math.pi)
