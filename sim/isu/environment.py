"""Site and laboratory environment: gravity, Earth rate, pier tilt, wobble, floor vibration.

Frames: E1 = up, E2 = east, E3 = north (report 000, Part IV). The pier's rotation relative to
the Earth is a small rotation vector eps(t) in E components (horizontal: about E and N);
the floor's translational acceleration is a(t) in E components.

These are the three noise processes of Chart I-9:
* rotational noise phi_theta: the tilt eps(t) = diurnal + wander + wobble, with covariance
  per horizontal axis (A^2/2) cos(w_d tau) + s_w^2 exp(-|tau|/tau_w)
  + sum_k (B_k^2/2) cos(w_k tau), the last a narrow band of tones about 1 cycle/min;
* translational noise phi_alpha: the floor vibration, a multitone with covariance
  sum_k (A_k^2/2) cos(w_k tau) per axis;
* accelerometer noise phi_n: white, q delta(tau), held in :mod:`sim.isu.unit`.
"""

from __future__ import annotations

import math

import numpy as np

from sim import units
from sim.isu.params import EnvironmentParams, SiteParams
from sim.noise import Multitone, Multitones, gauss_markov
from sim.rng import stream

DAY = 86400.0


class Site:
    """Latitude, local gravity and Earth rate; lambda is the colatitude as in report 000."""

    def __init__(self, p: SiteParams) -> None:
        self.latitude = math.radians(p.latitude_deg)
        self.colatitude = math.pi / 2 - self.latitude
        self.g = p.g_local_mps2
        self.omega_e = units.deg_per_hr(p.earth_rate_deg_per_hr)

    @property
    def earth_rate_e(self) -> np.ndarray:
        """Earth rate in E components (up, east, north)."""
        lam = self.colatitude
        return self.omega_e * np.array([math.cos(lam), 0.0, math.sin(lam)])

    @property
    def gravity_e(self) -> np.ndarray:
        """Specific force of a body at rest: g directed up (the report's 'gravity vector')."""
        return np.array([self.g, 0.0, 0.0])


class Environment:
    """The pier's tilt history and the floor's vibration, seeded from the run seed."""

    WANDER_KNOT = 60.0  # the only kinks of the tilt history: sim.isu.world aligns its cells on them
    WOBBLE_TONES = 8

    def __init__(self, p: EnvironmentParams, seed: int) -> None:
        self.p = p
        pt = p.pier_tilt
        self.diurnal_amp = units.arcsec(pt.diurnal_pp_arcsec / 2.0)
        az = math.radians(pt.diurnal_azimuth_deg)
        # Direction of the diurnal rotation axis in the horizontal plane (E, N components).
        self.diurnal_dir = np.array([0.0, math.cos(az), math.sin(az)])
        self.diurnal_phase = float(stream(seed, "env", "diurnal").uniform(0, 2 * math.pi))
        self.w_d = 2 * math.pi / DAY
        s_w = units.arcsec(pt.wander_sigma_arcsec)
        self.wander = [
            gauss_markov(self.WANDER_KNOT, s_w, pt.wander_tau_s, seed, "env", "wander", ax)
            for ax in ("E", "N")
        ]
        wb = p.wobble
        # A narrow band of tones about 1/period (width 1/coherence), rms = amplitude/sqrt(2):
        # smooth and closed form, with a coherence time of about coherence_s.
        f_b, df = 1.0 / wb.period_s, 1.0 / wb.coherence_s
        s_b = units.arcsec(wb.amplitude_arcsec) / math.sqrt(2.0)
        self.wobble = [
            Multitone(
                s_b, f_b - 0.5 * df, f_b + 0.5 * df, self.WOBBLE_TONES, seed, "env", "wobble", ax
            )
            for ax in ("E", "N")
        ]
        self._wobble_at = Multitones(self.wobble)  # the tilt at one instant
        v = p.vibration
        rms = v.rms_micro_g * units.MICRO_G
        self.vibration = [
            Multitone(rms, v.band_hz[0], v.band_hz[1], v.tones, seed, "env", "vibration", ax)
            for ax in ("U", "E", "N")
        ]
        self._vibration_at = Multitones(self.vibration)  # the velocity at one instant

    # --- rotational: pier tilt eps(t) ---
    def tilt(self, t: np.ndarray) -> np.ndarray:
        """Rotation vector of the pier relative to the Earth, shape (N, 3), E components."""
        return self.tilt_and_rate(t)[0]

    def tilt_rate(self, t: np.ndarray) -> np.ndarray:
        """Time derivative of :meth:`tilt` (E components), shape (N, 3)."""
        return self.tilt_and_rate(t)[1]

    def tilt_and_rate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The tilt and its rate, in one pass over the processes. One instant (most calls)
        takes the wander in Python floats and the two wobble axes in one stacked product:
        the operations of each process's own path in their order, so the same bits, a third
        of the time (issue 17)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        eps, rate = self._diurnal(t)
        if t.size == 1:
            self._add_wander_and_wobble_at(float(t[0]), eps, rate)
        else:
            self._add_wander_and_wobble(t, eps, rate)
        return eps, rate

    def _diurnal(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The diurnal tilt and its rate at the times t, shape (N, 3) each."""
        eps = np.zeros((t.size, 3))
        rate = np.zeros((t.size, 3))
        arg = self.w_d * t + self.diurnal_phase
        # np.outer's products (a[:, None] * b), without its checks: 1,500 calls a day
        eps += (self.diurnal_amp * np.sin(arg))[:, None] * self.diurnal_dir
        rate += (self.diurnal_amp * self.w_d * np.cos(arg))[:, None] * self.diurnal_dir
        return eps, rate

    def _add_wander_and_wobble(self, t: np.ndarray, eps: np.ndarray, rate: np.ndarray
                               ) -> None:
        """The wander's and the wobble's tilt and rate added to ``eps`` and ``rate``, each
        process evaluated on the array t."""
        for i, ax in enumerate((1, 2)):
            v, r = self.wander[i].value_and_slope(t)
            mv, mr = self.wobble[i].value_and_rate(t)
            eps[:, ax] += v + mv
            rate[:, ax] += r + mr

    def _add_wander_and_wobble_at(self, t: float, eps: np.ndarray, rate: np.ndarray
                                  ) -> None:
        """``_add_wander_and_wobble`` at one time (a row each), the same bits."""
        mv, mr = self._wobble_at.value_and_rate_at(t)
        for i, ax in enumerate((1, 2)):
            v, r = self.wander[i].value_and_slope_at(t)
            eps[0, ax] += v + mv[i]
            rate[0, ax] += r + mr[i]

    # --- translational: floor vibration ---
    def vibration_accel(self, t: float | np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return np.stack([m.value(t) for m in self.vibration], axis=-1)

    def vibration_velocity(self, t: float | np.ndarray) -> np.ndarray:
        """Integral of the vibration acceleration from 0 to t, shape (N, 3). One instant
        (most calls: a cell's edge) takes the three axes in one stacked product, the same
        elementwise operations and one dot product per axis as each axis's own ``integral``
        (the same bits, a quarter of the time: issue 17)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if t.size == 1:
            return self._vibration_at.integral_at(float(t[0]))[None, :]
        return np.stack([m.integral(t) for m in self.vibration], axis=-1)

    def vibration_velocity_each(self, t: np.ndarray) -> np.ndarray:
        """:meth:`vibration_velocity` at each of the times t with the bits of a single time."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return np.stack([m.integral_each(t) for m in self.vibration], axis=-1)

    # --- covariance functions of Chart I-9 (per horizontal axis / per axis) ---
    def tilt_covariance(self, tau: float | np.ndarray) -> np.ndarray:
        """phi_theta(tau): covariance of one horizontal tilt component, rad^2."""
        tau = np.abs(np.asarray(tau, dtype=float))
        pt = self.p.pier_tilt
        dd = self.diurnal_dir[1:]
        diurnal = 0.5 * self.diurnal_amp**2 * np.cos(self.w_d * tau) * float(np.mean(dd**2))
        wander = units.arcsec(pt.wander_sigma_arcsec) ** 2 * np.exp(-tau / pt.wander_tau_s)
        wobble = 0.5 * (self.wobble[0].covariance(tau) + self.wobble[1].covariance(tau))
        return diurnal + wander + wobble

    def vibration_covariance(self, tau: float | np.ndarray, axis: int = 0) -> np.ndarray:
        """phi_alpha(tau): covariance of the floor acceleration along one E axis, (m/s^2)^2."""
        return self.vibration[axis].covariance(tau)
