"""The ISU laboratory's physical world on one simpy environment (integer ns ticks)."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np
import simpy

from sim import units
from sim.isu.environment import Environment, Site
from sim.isu.integrator import CellIntegral
from sim.isu.oscillator import MasterOscillator
from sim.isu.params import WorldParams
from sim.isu.pulses import PulseLine
from sim.isu.table import FourAxisTable
from sim.isu.unit import Isu
from sim.timebase import seconds

CELL = Environment.WANDER_KNOT  # s; quadrature cells end on the tilt history's only kinks


class World:
    """Site, environment, table, ISU and oscillator; pulse lines by patch-panel name."""

    def __init__(self, params: WorldParams, seed: int, env: simpy.Environment | None = None):
        self.params = params
        self.seed = int(seed)
        self.env = env if env is not None else simpy.Environment()
        self.site = Site(params.site)
        self.environment = Environment(params.environment, self.seed)
        self.table = FourAxisTable(params.table, self.environment, self.seed)
        self.isu = Isu(params.isu, self.seed)
        self.oscillator = MasterOscillator(params.oscillator, self.seed)
        # integrated: gyro 1..3 smooth rate; accel k: (f2 - f1) and common-mode rate;
        # interpolated: w.O of gyro 1..3 (the J term)
        self.integral = CellIntegral(
            9,
            3,
            CELL,
            self._integrand,
            self.environment.vibration_velocity,
            self.table.breakpoints,
            self.table.abs_rate,
            self.environment.vibration_velocity_each,
        )
        self._change = self.env.event()
        self.revision = 0  # counts the changes of the world's future (table commands)
        self._held_values: tuple[np.ndarray, int, np.ndarray] | None = None
        self.lines: dict[str, PulseLine] = {}
        self._build_lines()

    # ----- time and change notification -----
    @property
    def now(self) -> float:
        """Simulated time, seconds."""
        return seconds(self.env.now)

    def changed(self) -> None:
        """Tell the world its future changed at now (a table command): drop predictions."""
        self.integral.invalidate_after(self.now)
        self.revision += 1
        self.notify()

    def notify(self) -> None:
        """Wake everything planning on the world (e.g. a re-patched counter); physics unchanged."""
        ev, self._change = self._change, self.env.event()  # a new one: its identity is news
        if ev.callbacks:  # processes yield at once; unwaited, it would only cost a step
            ev.succeed()

    @property
    def change_event(self) -> simpy.Event:
        return self._change

    # ----- kinematics -----
    def kinematics(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """T^BE (N,3,3), body angular rate w.r.t. inertial space (N,3), specific force (N,3)."""
        f = self.table.frames(np.atleast_1d(np.asarray(t, dtype=float)))
        t_bi, t_bo, t_br, t_bt, t_be = self._chain(f)
        rates = f["rates"]
        w_rel = (
            rates[4][:, None] * t_bi[None, :, 0]
            + rates[3][:, None] * t_bo[:, :, 0]
            + rates[2][:, None] * t_br[:, :, 0]
            + rates[1][:, None] * t_bt[:, :, 0]
            + np.einsum("nij,nj->ni", t_be, f["eps_rate"])
        )
        w_b = np.einsum("nij,j->ni", t_be, self.site.earth_rate_e) + w_rel
        a_b = np.einsum("nij,j->ni", t_be, self.site.gravity_e)
        return t_be, w_b, a_b

    def _chain(self, f: dict) -> tuple[np.ndarray, ...]:
        """T^BI and, from the table's frames ``f``, T^BO, T^BR, T^BT and T^BE."""
        t_bi = self.isu.t_bi
        t_bo = t_bi @ f["t_io"]
        t_br = t_bo @ f["t_or"]
        t_bt = t_br @ f["t_rt"]
        return t_bi, t_bo, t_br, t_bt, t_bt @ f["t_tf"] @ f["t_fe"]

    def attitude(self, t: float) -> np.ndarray:
        """True T^BE at t: ``kinematics``' without its rate and force (an autocollimator's
        reading asks for it 284 times a day)."""
        return self._chain(self.table.frames(np.atleast_1d(np.asarray(t, dtype=float))))[4][0]

    def mirror_normals(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """True mirror normals in E components (up, east, north)."""
        t_eb = self.attitude(t).T
        return t_eb @ self.isu.mirrors[0], t_eb @ self.isu.mirrors[1]

    def _integrand(self, t: np.ndarray, mid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rates at nodes t, and per piece (middles ``mid``) the vibration matrices.

        The matrix maps the floor's velocity change (E axes) to D1 (A.dv)/g on each f2 - f1
        integral, with the ISU attitude at the piece's middle: exact on a still table.
        """
        t_all, w_all, a_all = self.kinematics(np.concatenate((t, mid)))
        n = t.size
        w_b, a_b, t_be = w_all[:n], a_all[:n], t_all[n:]
        cols = [g.rate(w_b, a_b) for g in self.isu.gyros]
        for acc in self.isu.accels:
            cols.append(acc.difference_rate(a_b))
            cols.append(acc.common_rate(a_b))
        cols.extend(w_b @ g.O for g in self.isu.gyros)
        return np.stack(cols, axis=-1), self._vibration_matrices(t_be)

    def _vibration_matrices(self, t_be: np.ndarray) -> np.ndarray:
        out = np.zeros((t_be.shape[0], 9, 3))
        for k, acc in enumerate(self.isu.accels):
            a_e = np.einsum("nij,i->nj", t_be, acc.A)  # A in E components
            out[:, 3 + 2 * k, :] = acc.D1 * a_e / units.G0
        return out

    # ----- pulse lines -----
    def gyro_phase(self, k: int, t: float) -> float:
        g = self.isu.gyros[k]
        w_o = self.integral.interpolated(t)[k]
        ang = self.integral.value(t)[k] + g.J * w_o + float(g.noise_angle(t))
        return ang / g.dphi + g.phase0

    def _values_at(self, t: np.ndarray) -> np.ndarray:
        """``integral.values(t)``, kept for the next line asked at the same times (the six
        strings of a block of IEU samples share one evaluation) until the world changes."""
        held = self._held_values
        if held is not None and held[1] == self.revision and np.array_equal(held[0], t):
            return held[2]
        v = self.integral.values(t)
        self._held_values = (np.array(t, dtype=float), self.revision, v)
        return v

    def gyro_phases(self, k: int, t: np.ndarray) -> np.ndarray:
        """Gyro k's phase at each of the times t, with the bits of :meth:`gyro_phase` at each."""
        g = self.isu.gyros[k]
        w_o = self.integral.interpolations(t)[:, k]
        ang = self._values_at(t)[:, k] + g.J * w_o + g.noise_angle(t)
        return ang / g.dphi + g.phase0

    def string_phase(self, k: int, s: int, t: float) -> float:
        acc = self.isu.accels[k]
        v = self.integral.value(t)
        diff = v[3 + 2 * k] + acc.D1 * float(acc.noise.value(t)) / units.G0
        sign = -0.5 if s == 1 else 0.5
        return acc.f0 * t + v[4 + 2 * k] + sign * diff + acc.phase0[s - 1]

    def string_phases(self, k: int, s: int, t: np.ndarray) -> np.ndarray:
        """String s of accelerometer k: :meth:`string_phase` at each of the times t."""
        acc = self.isu.accels[k]
        v = self._values_at(t)
        diff = v[:, 3 + 2 * k] + acc.D1 * acc.noise.value(t) / units.G0
        sign = -0.5 if s == 1 else 0.5
        return acc.f0 * t + v[:, 4 + 2 * k] + sign * diff + acc.phase0[s - 1]

    def _build_lines(self) -> None:
        osc = self.oscillator
        for k, g in enumerate(self.isu.gyros, start=1):
            net = PulseLine(
                f"G{k}", partial(self.gyro_phase, k - 1), sample=(g.tau, g.sample_offset),
                phases=partial(self.gyro_phases, k - 1), world=self,
            )
            self.lines[f"G{k}"] = net
            for sign, suffix in ((1, "+"), (-1, "-")):
                line = PulseLine(f"G{k}{suffix}", net.phase, bipolar_sign=sign)
                line.net = net
                self.lines[line.name] = line
        for k in range(1, 4):
            for s in (1, 2):
                name = f"A{k}S{s}"
                self.lines[name] = PulseLine(name, partial(self.string_phase, k - 1, s),
                                             phases=partial(self.string_phases, k - 1, s),
                                             world=self)
        self.lines["TROT"] = PulseLine("TROT", lambda t: float(self.table.rotation_phase(t)),
                                       world=self)
        for name, div in (("OSC1", osc.p.s1_divider), ("OSC2", osc.p.s2_divider)):
            self.lines[name] = PulseLine(name, partial(_divided, osc.phase, div),
                                         phases=partial(_divided, osc.phase, div))

    def line(self, name: str) -> PulseLine:
        return self.lines[name]


def _divided(phase: Callable[[Any], Any], divider: int, t: Any) -> Any:
    """An oscillator output's phase: the master phase over its countdown divider."""
    return phase(t) / divider
