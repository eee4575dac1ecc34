"""The CIGTF gyrocompassing test station (report 001) on one simpy environment (integer ns).

Holds the two-axis fixture (Appendix II) with the gyro on it (Appendix I, ``SdfGyro``) and
what the averaging DVM adds to the torquer current. All random draws come from streams of
the run seed (``sim.rng``).

Magnitudes (our choice; the report's text gives none for the noise, only the dof: ten
10-s averages per orientation, 9 dof each, 900 over 25 runs):
  * S_T = 1 deg/hr per mA, so currents are a few mA and the GSF is about 4094 arcsec/mA.
  * White noise of one 10-s averaged current: 0.002 mA (0.002 deg/hr), i.e. a run sigma
    (eq. 19) of about GSF * sqrt(4 * 0.002^2 / 10) = 5.2 arcsec and phase sigmas (eq. 21)
    of about 1.0 arcsec (25 runs) and 1.6 arcsec (10 runs).
  * D_F random walk 2e-5 deg/hr/sqrt(s), turn-on shift 0.02 deg/hr (cancels in the
    four-orientation sum), warm-up transient 0.05 deg/hr with 1200 s time constant
    (e^-6 of it left after the 2-hour warm-up), loop settling 20 s.
  * Misalignments: a, b, c of 3 arcsec (levelled, aligned north), d, e, f of 2 arcsec
    (axes perpendicular within 5 arcsec), h, i, j of 30 arcsec (gyro in its mount).
"""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import simpy

from sim.cigtf.fixture import FixtureSpec, GyrocompassFixture, Misalignments, q_ge
from sim.cigtf.sdf_gyro import DriftModel, Dynamics, SdfGyro, steady_current
from sim.cigtf.setup import SetupAids, SetupSpec
from sim.rng import stream
from sim.timebase import seconds, ticks
from sim.units import ARCSEC, EARTH_RATE, deg_per_hr, to_arcsec

MA = 1e-3  # A
NOMINAL_ROTOR_V = 26.0  # spin motor excitation, V (a 26 V, 400 Hz gyro motor)
# the site latitude whose horizontal Earth rate is 12.59562 deg/sidereal hr (about 32.89 deg)
REPORT_LATITUDE_DEG = math.degrees(math.acos(12.59562 / 15.0))


def default_model() -> DriftModel:
    """An SDF gyro with S_T = 1 deg/hr per mA and drift terms of tenths of deg/hr."""
    return DriftModel(s_t=deg_per_hr(1.0) / MA, d_f=deg_per_hr(1.5), d_i=deg_per_hr(0.4),
                      d_o=deg_per_hr(-0.7), d_s=deg_per_hr(0.3), d_ii=deg_per_hr(0.05),
                      d_ss=deg_per_hr(0.02), d_io=deg_per_hr(0.1), d_is=deg_per_hr(0.03),
                      d_os=deg_per_hr(0.25))


def default_dynamics() -> Dynamics:
    return Dynamics(settle_tau=20.0, warmup_amplitude=deg_per_hr(0.05), warmup_tau=1200.0,
                    drift_walk=deg_per_hr(2e-5), turn_on_sd=deg_per_hr(0.02))


@dataclass(frozen=True)
class CigtfParams:
    latitude_deg: float = REPORT_LATITUDE_DEG  # 12.59562 deg/sidereal hr horizontal rate
    model: DriftModel = field(default_factory=default_model)
    dynamics: Dynamics = field(default_factory=default_dynamics)
    fixture: FixtureSpec = field(default_factory=FixtureSpec)
    level_sd_arcsec: float = 3.0  # a, b, c
    perpendicular_sd_arcsec: float = 2.0  # d, e, f
    mount_sd_arcsec: float = 30.0  # h, i, j
    slew_deg_s: float = 6.0  # fixture slew rate
    current_noise_ma: float = 0.002  # 1-sigma white noise of one 10-s averaged current
    average_s: float = 10.0
    # a, b, c as the section 4.1 set-up leaves them (levelled, aligned north from the
    # installed ones of ``setup``); False: drawn at level_sd_arcsec, no set-up
    pretest_setup: bool = True
    setup: SetupSpec = field(default_factory=SetupSpec)
    # the spin motor's excitation and the magnetic drift it causes (section 1's parameter
    # variation; 0: the Appendix I gyro, whose theta the rotor voltage leaves alone)
    rotor_voltage_v: float = NOMINAL_ROTOR_V
    magnetic_drift_deg_hr_per_gauss: float = 0.0  # at the nominal rotor voltage


def effective_model(p: CigtfParams) -> DriftModel:
    """The gyro's model at its rotor voltage: the magnetic drift scales with the voltage."""
    if not p.magnetic_drift_deg_hr_per_gauss:
        return p.model
    return replace(p.model, d_m=deg_per_hr(p.magnetic_drift_deg_hr_per_gauss)
                   * p.rotor_voltage_v / NOMINAL_ROTOR_V)


def draw_misalignments(p: CigtfParams, seed: int) -> Misalignments:
    """a..j from the seed; with the pre-test set-up, a, b, c as installed (the set-up
    procedure then levels and aligns the fixture through the set-up aids)."""
    rng = stream(seed, "cigtf", "misalignments")
    abc = ([p.setup.installed_azimuth_sd_arcsec] + [p.setup.installed_tilt_sd_arcsec] * 2
           if p.pretest_setup else [p.level_sd_arcsec] * 3)
    sd = abc + [p.perpendicular_sd_arcsec] * 3 + [p.mount_sd_arcsec] * 3
    return Misalignments(*(float(rng.normal(0.0, s)) * ARCSEC for s in sd))


class CigtfWorld:
    """Fixture, gyro and the DVM's noise; axis moves take slew time, then the loop settles."""

    def __init__(self, seed: int, params: CigtfParams | None = None,
                 env: simpy.Environment | None = None) -> None:
        self.seed = int(seed)
        self.p = params or CigtfParams()
        self.env = env if env is not None else simpy.Environment()
        self.latitude = math.radians(self.p.latitude_deg)
        self.fixture = GyrocompassFixture(draw_misalignments(self.p, self.seed), self.seed,
                                          self.p.fixture)
        self.aids = SetupAids(self.fixture, self.p.setup, self.seed)
        self.model = effective_model(self.p)
        self.gyro = SdfGyro(self.model, self.latitude, self.p.dynamics, self.seed)
        self.moving_until = 0.0
        self._readings = 0

    @property
    def now(self) -> float:
        return seconds(self.env.now)

    @property
    def misalignments(self) -> Misalignments:
        """a..j now (the set-up's screws and base adjustment change a, b, c)."""
        return self.fixture.misalignments

    def adjusted(self) -> None:
        """The fixture's base was tilted or turned: a running gyro settles to it."""
        if self.gyro.on_since is not None:
            self.gyro.moved(self.now, self.fixture.q_ge())

    # ----- fixture -----
    def start_move(self, vertical_deg: int, horizontal_deg: int, arrive: bool = True) -> float:
        """Slew to whole-degree positions; returns the arrival time (s). ``arrive=False``:
        the drive stops short (a fault) and the fixture stays where it was."""
        dv = abs(vertical_deg - self.fixture.vertical_deg)
        dh = abs(horizontal_deg - self.fixture.horizontal_deg)
        dur = max(min(dv, 360 - dv % 360), min(dh, 360 - dh % 360)) / self.p.slew_deg_s
        self.moving_until = self.now + dur
        if arrive:
            self.env.process(self._arrive(ticks(dur), vertical_deg % 360, horizontal_deg % 360))
        return self.moving_until

    def _arrive(self, dt: int, v: int, h: int) -> Generator[simpy.Event, Any, None]:
        yield self.env.timeout(dt)
        self.fixture.move_to(v, h)
        if self.gyro.on_since is not None:
            self.gyro.moved(self.now, self.fixture.q_ge())

    # ----- gyro -----
    def power_on(self) -> None:
        if self.gyro.on_since is None:
            self.gyro.power_on(self.now, self.fixture.q_ge())

    def power_off(self) -> None:
        self.gyro.power_off()

    def set_rotor_voltage(self, volts: float) -> None:
        """The spin motor's supply set to ``volts`` (gyro off): the model the next turn-on
        runs with, as if ``rotor_voltage_v`` had been configured (section 1's variation)."""
        if self.gyro.on_since is not None:
            raise RuntimeError("rotor voltage changed with the gyro running")
        self.p = replace(self.p, rotor_voltage_v=float(volts))
        self.model = effective_model(self.p)
        self.gyro.model = self.model

    def average_current_ma(self, t0: float, t1: float) -> float:
        """Mean torquer current over [t0, t1] (Simpson, 21 nodes) plus the DVM's noise, mA."""
        tt = np.linspace(t0, t1, 21)
        i = self.gyro.currents(tt)
        w = np.ones(21)
        w[1:-1:2], w[2:-1:2] = 4.0, 2.0
        mean = float(w @ i) / (3.0 * 20)
        self._readings += 1
        noise = stream(self.seed, "cigtf", "dvm", self._readings).normal(
            0.0, self.p.current_noise_ma)
        return mean / MA + float(noise)

    # ----- truth -----
    def truth_theta_arcsec(self) -> float:
        """Eq. 26: what the four-orientation sum leaves, from the true misalignments, drift
        terms and the fixture's fixed detent errors (eps = error of the 180 deg vertical
        detent, eta = -eps since orientation 4 returns to the 0 deg null; beta cancels)."""
        m, d = self.misalignments, self.model
        eps = self.fixture._detent("v", 180)
        eta = -eps
        ws, wc = EARTH_RATE * math.sin(self.latitude), EARTH_RATE * math.cos(self.latitude)
        rhs = (-4 * m.b * d.d_i + 4 * m.c * d.d_os - 4 * m.b * ws + 4 * (m.a + m.d) * wc
               + (3 * eps + eta) * wc)
        return to_arcsec(-rhs / (4 * wc)) + self.magnetic_theta_arcsec()

    def magnetic_theta_arcsec(self) -> float:
        """What the magnetic drift adds to theta (exact four-orientation sum, arcsec)."""
        if not self.model.d_m:
            return 0.0
        return self.exact_theta_arcsec(0) - self.exact_theta_arcsec(0, magnetic=False)

    def exact_theta_arcsec(self, v0_deg: int = 0, magnetic: bool = True) -> float:
        """theta of a noise-free run whose orientation 1 is at vertical ``v0_deg`` (the
        input-axis azimuth variation): the steady currents at the fixture's detents, the
        GSF of the +1 deg turn (eq. 14) and eq. 18, all exact (no small angles)."""
        model = self.model if magnetic else replace(self.model, d_m=0.0)
        fx, m = self.fixture, self.misalignments

        def i_ma(v: int, h: int) -> float:
            ang_v = math.radians(v) + fx._detent("v", v)
            ang_h = math.radians(h) + fx._detent("h", h)
            return steady_current(model, q_ge(m, ang_v, ang_h), self.latitude) / MA
        gsf = 900.0 / (i_ma(v0_deg, 0) - i_ma(v0_deg + 1, 0))
        return gsf * (i_ma(v0_deg, 0) + i_ma(v0_deg + 180, 180) - i_ma(v0_deg + 180, 0)
                      - i_ma(v0_deg, 180))

    def truth_budget(self) -> dict[str, float]:
        """Eq. 26 term by term from the true values, arcsec: the part of theta each term
        makes (b D_I, c D_OS, b omega sin, (3 epsilon + eta)/4) and ``north`` = -(a + d),
        the fixture's azimuth error; their sum is ``truth_theta_arcsec``."""
        m, d = self.misalignments, self.model
        eps = self.fixture._detent("v", 180)
        eta = -eps
        wc = EARTH_RATE * math.cos(self.latitude)
        return {"b D_I": to_arcsec(m.b * d.d_i / wc), "c D_OS": to_arcsec(-m.c * d.d_os / wc),
                "b omega sin": to_arcsec(m.b * math.tan(self.latitude)),
                "(3 epsilon + eta)/4": to_arcsec(-(3 * eps + eta) / 4),
                "north": to_arcsec(-(m.a + m.d))}
