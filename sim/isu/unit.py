"""The inertial sensing unit: three pulse-rebalance gyros (Chart IV-2), three two-string
vibrating-string accelerometers (Chart IV-1), two mirrors, and its mounting T^BI.

Gyro axes in the body frame (DOMAIN.md, from Chart III-9): gyro 1 G=B1, O=B3, S=-B2;
gyro 2 G=B2, O=B1, S=-B3; gyro 3 G=B3, O=B1, S=+B2. Accelerometer k: A_k along B_k.
The true axes are the nominal ones turned by the configured misalignments.
"""

from __future__ import annotations

import numpy as np

from sim import units
from sim.frames import rotation, transform_of_rotated
from sim.isu.params import AccelParams, GyroParams, IsuParams
from sim.noise import gauss_markov, random_walk

B = np.eye(3)
GYRO_AXES = (  # (G, O, S) nominal, body components
    (B[0], B[2], -B[1]),
    (B[1], B[0], -B[2]),
    (B[2], B[0], B[1]),
)
NOISE_KNOT = 0.05  # s; white noise is held as a random walk sampled at 20 Hz
DRIFT_KNOT = 10.0  # s


def _others(k: int) -> tuple[int, int]:
    """The two axes other than k, in order."""
    i, j = (m for m in range(3) if m != k)
    return i, j


def _misaligned(k: int, m_arcsec: tuple[float, float]) -> np.ndarray:
    """Unit vector B_k tipped towards the two other body axes (in index order) by m arcsec."""
    v = B[k].copy()
    for j, m in zip(_others(k), m_arcsec, strict=True):
        v = v + units.arcsec(m) * B[j]
    return v / np.linalg.norm(v)


class Gyro:
    """Pulse-rebalance SDF gyro; coefficients held in SI (rad, s, m/s^2)."""

    def __init__(self, k: int, p: GyroParams, seed: int) -> None:
        self.k = k
        self.p = p
        g0, o0, _ = GYRO_AXES[k]
        self.G = _misaligned(k, p.misalignment_arcsec)
        # Turn the output axis about G by the spin-axis rotation, then square it up.
        o = rotation(self.G * units.arcsec(p.spin_axis_rotation_arcsec)) @ o0
        o = o - (o @ self.G) * self.G
        self.O = o / np.linalg.norm(o)
        self.S = np.cross(self.G, self.O)  # G = O x S  =>  S = G x O
        c = units.DEG_PER_HR
        self.dphi = units.arcsec(p.scale_factor_arcsec_per_pulse)
        self.R = p.R_deg_hr * c
        self.B_I, self.B_O, self.B_S = (
            x * c / units.G0 for x in (p.B_I_deg_hr_g, p.B_O_deg_hr_g, p.B_S_deg_hr_g)
        )
        g2 = units.G0**2
        self.C_II, self.C_SS, self.C_IS, self.C_OS, self.C_IO = (
            x * c / g2
            for x in (
                p.C_II_deg_hr_g2,
                p.C_SS_deg_hr_g2,
                p.C_IS_deg_hr_g2,
                p.C_OS_deg_hr_g2,
                p.C_IO_deg_hr_g2,
            )
        )
        self.Q_II = p.Q_II_hr_deg / c
        self.Q_IS = p.Q_IS_hr_deg / c
        self.J = p.J_hr * units.HOUR
        self.tau = 1.0 / p.pulse_rate_hz
        self.max_rate = p.pulse_rate_hz * self.dphi
        arw = p.arw_deg_rt_hr * units.DEG / 60.0  # rad/sqrt(s)
        self.arw = random_walk(NOISE_KNOT, arw**2, seed, "gyro", k, "arw")
        self.drift = gauss_markov(
            DRIFT_KNOT, p.drift_sigma_deg_hr * c, p.drift_tau_s, seed, "gyro", k, "drift"
        )
        from sim.rng import stream

        rng = stream(seed, "gyro", k, "phase")
        self.phase0 = float(rng.uniform())
        self.sample_offset = float(rng.uniform()) * self.tau

    def rate(self, w: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Smooth part of the rebalance rate (rad/s) for body rates w and specific forces a (N, 3).

        Every term of Chart IV-2 except J (integrated exactly as J * (w.O)) and the noise.
        """
        wg, ws = w @ self.G, w @ self.S
        ag, ao, as_ = a @ self.G, a @ self.O, a @ self.S
        r = (
            wg
            + self.R
            + self.B_I * ag
            + self.B_O * ao
            + self.B_S * as_
            + self.C_II * ag * ag
            + self.C_SS * as_ * as_
            + self.C_IS * ag * as_
            + self.C_OS * ao * as_
            + self.C_IO * ag * ao
            + self.Q_II * wg * wg
            + self.Q_IS * wg * ws
        )
        return np.clip(r, -self.max_rate, self.max_rate)

    def noise_angle(self, t: float | np.ndarray) -> float | np.ndarray:
        """Angle (rad) added by random walk and random drift from 0 to t."""
        return self.arw.value(t) + self.drift.integral(t)


class Accelerometer:
    """Two-string vibrating-string accelerometer (Chart IV-1).

    f2 - f1 = D1 (u + D0 + D2 u^2 + D3 u^3) with u = a.A in g.
    """

    def __init__(self, k: int, p: AccelParams, seed: int) -> None:
        self.k = k
        self.p = p
        self.A = _misaligned(k, p.misalignment_arcsec)
        self.D1, self.D0, self.D2, self.D3 = p.D1_pps_per_g, p.D0_g, p.D2_g_per_g2, p.D3_g_per_g3
        self.f0 = p.f0_hz
        self.kappa = p.common_mode_hz_per_g2
        q = (p.noise_micro_g_rt_hz * units.MICRO_G) ** 2
        self.noise = random_walk(NOISE_KNOT, q, seed, "accel", k, "noise")  # m/s
        from sim.rng import stream

        rng = stream(seed, "accel", k, "phase")
        self.phase0 = (float(rng.uniform()), float(rng.uniform()))

    def difference_rate(self, a: np.ndarray) -> np.ndarray:
        """f2 - f1 (pulses/s) for specific forces a (N, 3) in m/s^2."""
        u = (a @ self.A) / units.G0
        return self.D1 * (u + self.D0 + self.D2 * u * u + self.D3 * u**3)

    def common_rate(self, a: np.ndarray) -> np.ndarray:
        """Common-mode shift of both strings (Hz); cancels in f2 - f1."""
        u = (a @ self.A) / units.G0
        return self.kappa * u * u


class Isu:
    """Instruments, mirrors and mounting of the ISU."""

    def __init__(self, p: IsuParams, seed: int) -> None:
        self.p = p
        self.t_bi = transform_of_rotated(np.radians(np.array(p.t_bi_rotation_deg)))
        self.gyros = [Gyro(k, gp, seed) for k, gp in enumerate(p.gyros)]
        self.accels = [Accelerometer(k, ap, seed) for k, ap in enumerate(p.accels)]
        # Mirror 1 defines B1; mirror 2 lies in the B1-B2 plane, off B2 by the mirror error.
        d = units.arcsec(p.mirror_nonorthogonality_arcsec)
        self.mirrors = (B[0].copy(), np.cos(d) * B[1] + np.sin(d) * B[0])
