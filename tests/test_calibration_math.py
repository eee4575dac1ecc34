"""Calibration computations (report 000, Charts II-15, II-16, II-4.2, II-4.3) on synthetic data.

The data come from a generator written here, independent of ``procedures.isu.calibration``:
* instruments: Chart IV-2 (gyros, every term including Q and whole-turn averaging done
  numerically) and Chart IV-1 (accelerometers, strings counted separately), with the default
  configuration's truth and misalignments;
* geometry: the table chain T^BE = T^BI T^IO T^OR T^RT T^TF (Chart I-4) with junction
  non-orthogonality, resolver cyclic errors, servo scatter, a survey at position 0 with
  autocollimator error, Chart I-5 settings rounded to the resolver's 0.01 arcsec, and level
  corrections read on graduated bubbles;
* noise: count and clock quantization, angle random walk, random drift, accelerometer white
  noise, pier tilt (diurnal, wander, a wobble of tones in a band), sampled as processes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from procedures.isu.calibration import (
    AccelPosition,
    CalibrationData,
    Constants,
    GyroPosition,
    NoiseSpec,
    TableGeometry,
    calibrate,
    estimate,
    predicted_sigmas,
)
from procedures.isu.calibration import chart_ii16 as chart
from procedures.isu.calibration.kernels import Functional, band_nodes, cosine_gram, exp_gram
from procedures.isu.calibration.reduce import reduce
from station.config.isu import default_dict

CFG = default_dict()
AS = math.pi / (180 * 3600)  # rad per arcsec
S1 = 1e-6  # s per clock tick
G_STD = 9.80665
E = np.eye(3)
GYRO_TERMS = ("R", "B_I", "B_O", "B_S", "C_II", "C_SS", "C_IS", "C_OS", "C_IO", "Q_II", "Q_IS")
NOMINAL = ((E[0], E[2], -E[1]), (E[1], E[0], -E[2]), (E[2], E[0], E[1]))  # (G, O, S)
UP = {
    1: E[0],
    3: E[1],
    5: E[2],
    13: (E[0] + E[1]) / math.sqrt(2),
    14: (E[0] + E[2]) / math.sqrt(2),
    15: (E[1] + E[2]) / math.sqrt(2),
}
PHI0_DEG = (0.0, 90.0, 90.0, 0.0)
W_T = 15.0  # deg/s, table rate in positions 1-6
TURNS = 10


# ----------------------------------------------------------------------------- frames


def rot(v) -> np.ndarray:
    """Rotation matrix of rotation vector v (Rodrigues)."""
    v = np.asarray(v, dtype=float)
    th = np.linalg.norm(v)
    if th < 1e-15:
        return np.eye(3)
    k = v / th
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(th) * kx + (1 - math.cos(th)) * kx @ kx


def gimbal(p: float) -> np.ndarray:
    c, s = math.cos(p), math.sin(p)
    return np.array([[0, 1, 0], [c, 0, -s], [-s, 0, -c]])


def tilted(k: int, m_arcsec) -> np.ndarray:
    """B_k tipped towards the other two body axes (index order) by m arcsec."""
    v = E[k].copy()
    for j, m in zip([j for j in range(3) if j != k], m_arcsec, strict=True):
        v = v + m * AS * E[j]
    return v / np.linalg.norm(v)


# ----------------------------------------------------------------------------- truth


class Truth:
    """Default-config instruments: Chart IV-1 and IV-2 coefficients and true axes."""

    def __init__(self) -> None:
        site = CFG["site"]
        lat = math.radians(site["latitude_deg"])
        w = site["earth_rate_deg_per_hr"]
        self.ws, self.wc = w * math.cos(lat), w * math.sin(lat)  # colatitude = 90 - lat
        self.g = site["g_local_mps2"] / G_STD
        self.gyros = []
        for k, p in enumerate(CFG["isu"]["gyros"]):
            G = tilted(k, p["misalignment_arcsec"])
            o = rot(G * p["spin_axis_rotation_arcsec"] * AS) @ NOMINAL[k][1]
            o = o - (o @ G) * G
            O = o / np.linalg.norm(o)  # noqa: E741
            coef = {t: p[next(f for f in p if f.startswith(t + "_"))] for t in GYRO_TERMS}
            dphi = p["scale_factor_arcsec_per_pulse"] / 3600.0  # deg/pulse
            self.gyros.append(dict(G=G, O=O, S=np.cross(G, O), coef=coef, dphi=dphi))
        self.accels = []
        for k, p in enumerate(CFG["isu"]["accels"]):
            self.accels.append(
                dict(
                    A=tilted(k, p["misalignment_arcsec"]),
                    D1=p["D1_pps_per_g"],
                    D0=p["D0_g"],
                    D2=p["D2_g_per_g2"],
                    D3=p["D3_g_per_g3"],
                    f0=p["f0_hz"],
                    kappa=p["common_mode_hz_per_g2"],
                )
            )
        self.t_bi = rot(np.radians(CFG["isu"]["t_bi_rotation_deg"])).T

    def gyro_rate(self, k: int, w: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Chart IV-2, pulses/s, for rows of w (deg/hr) and a (g)."""
        gy = self.gyros[k]
        c = gy["coef"]
        wg, ws = w @ gy["G"], w @ gy["S"]
        ag, ao, as_ = a @ gy["G"], a @ gy["O"], a @ gy["S"]
        r = (
            wg
            + c["R"]
            + c["B_I"] * ag
            + c["B_O"] * ao
            + c["B_S"] * as_
            + c["C_II"] * ag * ag
            + c["C_SS"] * as_ * as_
            + c["C_IS"] * ag * as_
            + c["C_OS"] * ao * as_
            + c["C_IO"] * ag * ao
            + c["Q_II"] * wg * wg
            + c["Q_IS"] * wg * ws
        )
        return r / 3600.0 / gy["dphi"]

    def turning_rate(self, k: int, r: np.ndarray) -> float:
        """Mean pulse rate over whole turns about body r at W_T (numerical average)."""
        p = np.cross(r, E[np.argmin(np.abs(r))])
        p /= np.linalg.norm(p)
        q = np.cross(r, p)
        th = np.linspace(0, 2 * math.pi, 64, endpoint=False)
        up = np.outer(np.cos(th), p) + np.outer(np.sin(th), q)
        w = (3600 * W_T - self.ws) * r[None, :] + self.wc * up  # R1 points south
        return float(np.mean(self.gyro_rate(k, w, self.g * up)))

    def accel_diff(self, k: int, u: np.ndarray) -> float:
        a = self.accels[k]
        x = self.g * (a["A"] @ u)
        return a["D1"] * (x + a["D0"] + a["D2"] * x * x + a["D3"] * x**3)

    def expected(self) -> dict[tuple[str, str], float]:
        out = {}
        for k, gy in enumerate(self.gyros, start=1):
            out[(f"gyro{k}", "DeltaPhi")] = gy["dphi"]  # deg/pulse (Chart II-5)
            for j in range(3):
                out[(f"gyro{k}", f"G.B{j + 1}")] = gy["G"][j]
            for t in GYRO_TERMS[:9]:
                out[(f"gyro{k}", t)] = gy["coef"][t]
        for k, a in enumerate(self.accels, start=1):
            out[(f"accel{k}", "D1")] = a["D1"]
            for j in range(3):
                out[(f"accel{k}", f"A.B{j + 1}")] = a["A"][j]
            for t in ("D0", "D2", "D3"):
                out[(f"accel{k}", t)] = a[t]
        return out


TRUTH = Truth()


# ----------------------------------------------------------------------------- the laboratory


def chart_i5(t_bi: np.ndarray, m: int) -> tuple[float, float]:
    x = t_bi.T @ UP[m]
    p3 = math.acos(float(np.clip(x[0], -1, 1)))
    p4 = math.atan2(x[1], x[2]) if math.hypot(x[1], x[2]) > 1e-12 else 0.0
    return p3, p4


def base_of(m: int) -> int:
    return m if m in (13, 14, 15) else 2 * (((m - 1) % 6) // 2) + 1


class Geometry:
    """One draw of the table's imperfections, the survey, and every setting's true frames.

    Emulates the procedures as built: the survey (Chart I-2) at position 0 = (0, 90, 90, 0)
    averages N autocollimator and bubble readings, enters phi^0 as reading minus bubble
    correction and adds the base-azimuth step's result to phi2; every position re-commands
    phi1..phi4, and at 7-15 reads the bubbles once and re-commands phi1, phi3 corrected
    (``procedures.isu.common.set_position``).
    """

    RES = 0.01 * AS  # resolver resolution: settings are commanded in its steps
    BASE_TILT = (12.0, -8.0)  # arcsec about east and north: levelled out by the bubbles

    def __init__(self, rng: np.random.Generator | None, ns: NoiseSpec) -> None:
        self.rng, self.ns = rng, ns
        if rng is None:
            self.n = {j: np.zeros(3) for j in ("IO", "OR", "RT")}
            self.res = {i: (0.0, 0.0, 0.0, 0.0) for i in (1, 2, 3, 4)}
        else:
            no = ns.nonorthogonality_arcsec * AS
            self.n = {j: rng.normal(0, no, 3) for j in ("IO", "OR", "RT")}
            a = ns.resolver_cyclic_arcsec * AS
            h1, h2 = ns.resolver_harmonics
            self.res = {i: (h1 * a, h2 * a, *rng.uniform(0, 2 * math.pi, 2)) for i in (1, 2, 3, 4)}
        self.t_fe = rot(np.array([0.0, *self.BASE_TILT]) * AS).T
        # --- survey at position 0 ---
        nread = ns.survey_readings
        p0 = [self.land(i + 1, math.radians(c)) for i, c in enumerate(PHI0_DEG)]
        r0 = [p + self.err(i + 1, p) for i, p in enumerate(p0)]  # resolver readings
        t_re0 = self.rotary(p0[1], p0[0])
        t_be0 = self.inner(p0[3], p0[2]) @ t_re0
        c1, c3 = self.bubbles(t_re0, nread)
        ac = self.normal(ns.autocollimator_arcsec * AS / math.sqrt(nread), 3)
        meas = rot(ac).T @ t_be0
        az = float(self.normal(ns.survey_azimuth_arcsec * AS, 1)[0])
        self.pos0 = (r0[0] - c1, r0[1] + az, r0[2] - c3, r0[3])
        chain0 = gimbal(self.pos0[3]) @ gimbal(self.pos0[2]) @ gimbal(self.pos0[1])
        self.t_bi_hat = meas @ (chain0 @ gimbal(self.pos0[0])).T
        self.settings = {}
        for m in (1, 3, 5, 13, 14, 15):
            p3, p4 = chart_i5(self.t_bi_hat, m)
            self.settings[m] = (round(p3 / self.RES) * self.RES, round(p4 / self.RES) * self.RES)
        self.column2 = {
            m: tuple(self.t_bi_hat @ gimbal(p4) @ gimbal(p3) @ E[1])
            for m, (p3, p4) in self.settings.items()
        }

    def normal(self, sigma: float, n: int) -> np.ndarray:
        return np.zeros(n) if self.rng is None else self.rng.normal(0, sigma, n)

    def err(self, axis: int, p: float) -> float:
        a1, a2, f1, f2 = self.res[axis]
        return a1 * math.sin(p + f1) + a2 * math.sin(2 * p + f2)

    def land(self, axis: int, cmd: float) -> float:
        """True angle where the servo leaves the resolver reading cmd plus its scatter."""
        return (
            cmd - self.err(axis, cmd) + float(self.normal(self.ns.table_setting_arcsec * AS, 1)[0])
        )

    def nn(self, j: str) -> np.ndarray:
        return rot(self.n[j]).T  # transform of a frame turned by n

    def inner(self, p4: float, p3: float) -> np.ndarray:
        """T^BR = T^BI T^IO T^OR with the junctions' non-orthogonality."""
        return TRUTH.t_bi @ gimbal(p4) @ self.nn("IO") @ gimbal(p3) @ self.nn("OR")

    def rotary(self, p2: float, p1: float) -> np.ndarray:
        """T^RE = T^RT T^TF T^FE."""
        return gimbal(p2) @ self.nn("RT") @ gimbal(p1) @ self.t_fe

    def bubbles(self, t_re: np.ndarray, n: int) -> tuple[float, float]:
        """Mean of n bubble readings: corrections for phi1 and phi3, rad (graduated)."""
        r1, r2 = t_re[0], t_re[1]
        true = np.array([r1[2], -r1[1] * math.copysign(1.0, r2[2])]) / AS
        if self.rng is None:
            return tuple(true * AS)  # type: ignore[return-value]
        q = self.ns.bubble_graduation_arcsec
        noisy = true[:, None] + self.rng.normal(0, self.ns.bubble_noise_arcsec, (2, n))
        return tuple(np.mean(np.round(noisy / q) * q, axis=1) * AS)  # type: ignore[return-value]

    def commanded(self, m: int) -> tuple[float, float]:
        p3, p4 = self.settings[base_of(m)]
        if m <= 12 and ((m - 1) % 6) % 2 == 1:
            p3 += math.pi
        return p3, p4

    def turning_axis(self, m: int) -> np.ndarray:
        c3, c4 = self.commanded(m)
        return self.inner(self.land(4, c4), self.land(3, c3))[:, 0]

    def static_frame(self, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """True body components of up, east, north at a level-corrected position 7-15."""
        c3, c4 = self.commanded(m)
        p1, p2, p4 = self.land(1, 0.0), self.land(2, math.pi / 2), self.land(4, c4)
        b1, b3 = self.bubbles(self.rotary(p2, p1), 1)
        p1, p3 = self.land(1, b1), self.land(3, c3 + b3)
        t_be = self.inner(p4, p3) @ self.rotary(p2, p1)
        return t_be[:, 0], t_be[:, 1], t_be[:, 2]

    def table_geometry(self) -> TableGeometry:
        return TableGeometry(
            t_bi=tuple(tuple(r) for r in self.t_bi_hat),
            phi0_deg=tuple(math.degrees(x) for x in self.pos0),
            settings_deg={m: tuple(math.degrees(x) for x in v) for m, v in self.settings.items()},
        )


class Environment:
    """Pier tilt (east, north) and gyro random drift sampled on a 2 s grid over the day."""

    DT = 2.0
    END = 40000.0

    def __init__(self, rng: np.random.Generator | None, ns: NoiseSpec) -> None:
        self.t = np.arange(0.0, self.END + self.DT, self.DT)
        n = self.t.size
        self.tilt = np.zeros((2, n))
        self.drift = np.zeros((3, n))
        if rng is None:
            return
        amp = 0.5 * ns.tilt_diurnal_pp_arcsec * AS
        az = math.radians(ns.tilt_diurnal_azimuth_deg)
        d = amp * np.sin(2 * math.pi * self.t / 86400 + rng.uniform(0, 2 * math.pi))
        self.tilt += np.outer([math.cos(az), math.sin(az)], d)
        self.tilt += self._ou(rng, ns.tilt_wander_sigma_arcsec * AS, ns.tilt_wander_tau_s, 2)
        fb, df = 1 / ns.wobble_period_s, 1 / ns.wobble_coherence_s
        rms = ns.wobble_amplitude_arcsec * AS / math.sqrt(2)
        for ax in range(2):
            f = rng.uniform(fb - df / 2, fb + df / 2, 8)
            ph = rng.uniform(0, 2 * math.pi, 8)
            self.tilt[ax] += (
                rms * math.sqrt(2 / 8) * np.cos(np.outer(self.t, 2 * math.pi * f) + ph).sum(1)
            )
        self.drift = self._ou(rng, ns.gyro_drift_sigma_deg_hr, ns.gyro_drift_tau_s, 3)

    def _ou(self, rng, sigma: float, tau: float, rows: int) -> np.ndarray:
        """Stationary Gauss-Markov rows: x_i = a x_(i-1) + w_i, x_0 ~ N(0, sigma^2)."""
        a = math.exp(-self.DT / tau)
        w = rng.normal(0, sigma * math.sqrt(1 - a * a), (rows, self.t.size))
        w[:, 0] = rng.normal(0, sigma, rows)
        return lfilter([1.0], [1.0, -a], w, axis=1)

    def at(self, x: np.ndarray, t: float) -> np.ndarray:
        return np.array([np.interp(t, self.t, row) for row in x])

    def mean(self, x: np.ndarray, a: float, b: float) -> np.ndarray:
        grid = np.concatenate(([a], self.t[(self.t > a) & (self.t < b)], [b]))
        vals = np.array([np.interp(grid, self.t, row) for row in x])
        return np.trapezoid(vals, grid, axis=1) / (b - a)


def constants(geo: Geometry) -> Constants:
    return Constants(
        g=TRUTH.g,
        w_sin_lambda=TRUTH.ws,
        w_cos_lambda=TRUTH.wc,
        s1_t=S1,
        s_phi=360.0,
        t_br_column2=geo.column2,
    )


SPEC = NoiseSpec()


def make_data(rng: np.random.Generator | None, ns: NoiseSpec = SPEC) -> CalibrationData:
    """One calibration day: gyro positions 1-15, accelerometer positions 7-15."""
    geo = Geometry(rng, ns)
    env = Environment(rng, ns)
    noisy = rng is not None

    def uniform_diff(scale: float = 1.0) -> float:
        return scale * float(rng.uniform() - rng.uniform()) if noisy else 0.0

    gyro = {}
    for m in range(1, 16):
        if m <= 6:
            t0, T = 1000.0 + 500 * (m - 1), TURNS * 360 / W_T
        else:
            t0, T = 5000.0 + 800 * (m - 7), 600.0
        if m <= 6:
            r = geo.turning_axis(m)
            rates = [TRUTH.turning_rate(k, r) for k in range(3)]
            d_tilt = env.at(env.tilt, t0 + T) - env.at(env.tilt, t0)
            tilt_angle = [-(TRUTH.gyros[k]["G"] @ r) * d_tilt[1] for k in range(3)]
        else:
            u, e, n = geo.static_frame(m)
            w = TRUTH.wc * u + TRUTH.ws * n
            rates = [float(TRUTH.gyro_rate(k, w[None], TRUTH.g * u[None])[0]) for k in range(3)]
            d_tilt = env.at(env.tilt, t0 + T) - env.at(env.tilt, t0)
            tilt_angle = [
                d_tilt @ [TRUTH.gyros[k]["G"] @ e, TRUTH.gyros[k]["G"] @ n] for k in range(3)
            ]
        drift = env.mean(env.drift, t0, t0 + T)
        delta = []
        for k in range(3):
            dphi = TRUTH.gyros[k]["dphi"]
            angle = 0.0  # deg
            if noisy:
                angle += rng.normal(0, ns.gyro_arw_deg_rt_hr * math.sqrt(T / 3600))
                angle += drift[k] * T / 3600 + math.degrees(tilt_angle[k])
            counts = rates[k] * T + angle / dphi
            tau = 1 / ns.gyro_sample_rate_hz
            delta.append(counts + uniform_diff() + uniform_diff(rates[k] * tau))
        n1 = T / S1 if m > 6 else T / S1 + uniform_diff()
        extra = {"n_phi": TURNS} if m <= 6 else {}
        gyro[m] = GyroPosition(n1=n1, delta=tuple(delta), t0=t0, t1=t0 + T, **extra)

    accel = {}
    for m in range(7, 16):
        t0 = 14000.0 + 2200 * (m - 7)
        t_lev = t0 - 100.0
        u, e, n = geo.static_frame(m)
        gamma, n1s = {}, {}
        for k in range(3):
            ac = TRUTH.accels[k]
            vertical = m in (2 * k + 7, 2 * k + 8)
            T_nom = 600.0 if vertical else 1800.0
            F = TRUTH.accel_diff(k, u)
            cm = ac["kappa"] * (TRUTH.g * (ac["A"] @ u)) ** 2
            f_true = (ac["f0"] - F / 2 + cm, ac["f0"] + F / 2 + cm)
            g_preset = round(T_nom * ac["f0"])
            gates = [g_preset / f for f in f_true]
            white = [0.0, 0.0]
            if noisy:  # one white-noise process seen over two nested gates
                q = (ns.accel_white_micro_g_rt_hz * 1e-6) ** 2
                short, long_ = sorted(range(2), key=lambda i: gates[i])
                ms = rng.normal(0, math.sqrt(q / gates[short]))
                rest = rng.normal(0, math.sqrt(q / (gates[long_] - gates[short])))
                white[short] = ms
                white[long_] = (gates[short] * ms + (gates[long_] - gates[short]) * rest) / gates[
                    long_
                ]
            lev = env.at(env.tilt, t_lev)
            for ell in range(2):
                d_eps = env.mean(env.tilt, t0, t0 + gates[ell]) - lev
                du = TRUTH.g * (ac["A"] @ (d_eps[0] * n - d_eps[1] * e))
                sign = -0.5 if ell == 0 else 0.5
                f = f_true[ell] + sign * ac["D1"] * (du + white[ell])
                gamma[(k + 1, ell + 1)] = g_preset
                n1s[(k + 1, ell + 1)] = g_preset / (f * S1) + uniform_diff()
        accel[m] = AccelPosition(gamma=gamma, n1=n1s, t0=t0, t1=t0 + 1800.0, t_level=t_lev)
    return CalibrationData(
        constants=constants(geo), gyro=gyro, accel=accel, geometry=geo.table_geometry()
    )


# ----------------------------------------------------------------------------- (a) noise free


def misalignment_bound() -> float:
    """Largest angle of any true G, O, S from its nominal axis, rad."""
    return max(
        math.acos(min(1.0, float(gy[x] @ NOMINAL[k][i])))
        for k, gy in enumerate(TRUTH.gyros)
        for i, x in enumerate(("G", "O", "S"))
    )


def tolerances() -> dict[tuple[str, str], float]:
    """What the closed forms neglect, per constant (noise-free data, exact geometry).

    * DeltaPhi, G.B: nothing at equal table rates (whole turns cancel every even term); the
      settings are rounded to the resolver's 0.01 arcsec, so G.B to 2e-7.
    * R, B, C: the g-terms use nominal O, S (and G): unbalance times misalignment m (about
      1e-3 deg/hr) and compliance times 2m; R and B get 2 B m, the square compliances 4 B m,
      the product compliances (which add 2 R, sqrt2 times two B, and C) 10 B m; Q terms at
      Earth rate (< 1e-6 deg/hr) are far below.
    * Accelerometers: D2 and D3 times misalignments (< 1e-8 of D1) and the 0.01 arcsec
      resolver rounding (5e-8 rad at the bisector, doubled in D1 = 2W - V).
    """
    m = misalignment_bound()
    bmax = max(abs(gy["coef"][t]) for gy in TRUTH.gyros for t in ("B_I", "B_O", "B_S"))
    out = {}
    for k in (1, 2, 3):
        g = f"gyro{k}"
        out[(g, "DeltaPhi")] = 1e-9 * 3.0 / 3600.0
        for j in (1, 2, 3):
            out[(g, f"G.B{j}")] = 2e-7
        for t in ("R", "B_I", "B_O", "B_S"):
            out[(g, t)] = 2 * bmax * m
        for t in ("C_II", "C_SS"):
            out[(g, t)] = 4 * bmax * m
        for t in ("C_IS", "C_OS", "C_IO"):
            out[(g, t)] = 10 * bmax * m
        a = f"accel{k}"
        out[(a, "D1")] = 4e-7 * 2000
        for j in (1, 2, 3):
            out[(a, f"A.B{j}")] = 2e-7
        out[(a, "D0")] = 1e-9
        out[(a, "D2")] = 1e-8
        out[(a, "D3")] = 4e-7
    return out


NOISE_FREE = make_data(None)


def test_noise_free_recovery():
    est = estimate(reduce(NOISE_FREE).values, NOISE_FREE.constants)
    truth, tol = TRUTH.expected(), tolerances()
    bad = {r: (est[r], v, tol[r]) for r, v in truth.items() if not abs(est[r] - v) <= tol[r]}
    assert not bad, bad
    # the geometry really has the small elements the print drops (e.g. T12^BR1)
    assert 0 < abs(NOISE_FREE.constants.t_br_column2[1][0]) < 1e-6


def test_printed_sign_slips_would_show():
    """The printed Earth-rate signs of B_S (gyros 1 and 2, Chart II-15) would miss the truth
    by 2 W cos(lambda)(G.B)/g, several times the closed forms' tolerance."""
    est = estimate(reduce(NOISE_FREE).values, NOISE_FREE.constants)
    tol = tolerances()
    for k, j in ((1, 2), (2, 3)):
        row = (f"gyro{k}", "B_S")
        printed = est[row] - 2 * TRUTH.wc * est[(f"gyro{k}", f"G.B{j}")] / TRUTH.g
        truth = TRUTH.gyros[k - 1]["coef"]["B_S"]
        assert abs(est[row] - truth) <= tol[row] < abs(printed - truth) / 3


# ----------------------------------------------------------------------------- (b) partial


def subset(data: CalibrationData, positions: set[int], **extra) -> CalibrationData:
    return CalibrationData(
        constants=data.constants,
        gyro={m: p for m, p in data.gyro.items() if m in positions},
        accel={m: p for m, p in data.accel.items() if m in positions},
        geometry=data.geometry,
        **extra,
    )


def determined(positions: set[int], last: bool = False) -> dict[tuple[str, str], bool]:
    out = {}
    for k in (1, 2, 3):
        for p in chart.GYRO:
            req = chart.gyro_requirement(p, k)
            out[(f"gyro{k}", p)] = req is not None and chart.satisfied(req, positions)
        for p in chart.ACCEL:
            out[(f"accel{k}", p)] = chart.satisfied(chart.accel_requirement(p, k, last), positions)
    return out


def check_partial(positions: set[int], last: bool = False) -> None:
    extra = {
        "last_d1d3": {k: TRUTH.accels[k - 1]["D1"] * TRUTH.accels[k - 1]["D3"] for k in (1, 2, 3)}
    }
    data = subset(NOISE_FREE, positions, **(extra if last else {}))
    est = estimate(reduce(data).values, data.constants)
    want = determined(positions, last)
    wrong = {r: (est[r], want[r]) for r in want if (est[r] is not None) != want[r]}
    assert not wrong, (sorted(positions), wrong)


@pytest.mark.parametrize(
    "positions",
    [
        {7, 8},
        {1, 2, 3, 4, 5, 6, 7, 8},
        {1, 2, 3, 4, 5, 6, 11, 12},
        {7, 8, 9, 10, 13},
        {7, 8, 11, 12, 13},
        set(range(1, 13)),
        set(range(1, 16)) - {13},
        set(range(1, 16)) - {9},
    ],
)
def test_partial_calibration_matches_chart_ii16(positions):
    check_partial(positions)


def test_partial_calibration_examples():
    # only 7, 8: gyro 1's B_I needs (1, 2) and the scale factor; nothing is determined
    data = subset(NOISE_FREE, {7, 8})
    est = estimate(reduce(data).values, data.constants)
    assert est[("gyro1", "B_I")] is None and est[("accel1", "D1")] is None
    # accelerometer 1: D1 with 7, 8, 13 and D0 from 9, 10
    data = subset(NOISE_FREE, {7, 8, 9, 10, 13})
    est = estimate(reduce(data).values, data.constants)
    for p in ("D1", "D0", "D2", "D3", "A.B1", "A.B2"):
        assert est[("accel1", p)] is not None, p
    assert est[("accel1", "A.B3")] is None and est[("accel3", "D1")] is None
    # step 7: with the last (D1 D3), D1 needs no bisector; D3 itself stays undetermined
    last = {k: TRUTH.accels[k - 1]["D1"] * TRUTH.accels[k - 1]["D3"] for k in (1, 2, 3)}
    data = subset(NOISE_FREE, set(range(7, 13)), last_d1d3=last)
    est = estimate(reduce(data).values, data.constants)
    for k in (1, 2, 3):
        assert est[(f"accel{k}", "D3")] is None
        assert abs(est[(f"accel{k}", "D1")] - TRUTH.accels[k - 1]["D1"]) < 1e-6
    check_partial(set(range(7, 13)), last=True)
    check_partial({7, 8}, last=True)


def test_random_subsets_match_chart_ii16():
    rng = np.random.default_rng(16)
    for _ in range(60):
        positions = {m for m in range(1, 16) if rng.uniform() < 0.75}
        check_partial(positions, last=bool(rng.uniform() < 0.3))


def test_result_rows():
    data = subset(NOISE_FREE, {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12})
    rows = calibrate(data)
    assert len(rows) == 3 * 16 + 3 * 7
    by = {(r.instrument, r.parameter): r for r in rows}
    r = by[("gyro1", "B_I")]
    assert r.estimate is not None and r.sigma is not None and r.positions == "7, 8 (1, 2)"
    assert by[("gyro1", "C_IS")].estimate is None and "not determined" in by[("gyro1", "C_IS")].note
    assert by[("gyro2", "Q_II")].estimate is None and by[("gyro2", "J")].sigma is None
    assert by[("gyro1", "DeltaPhi")].units == "deg/pulse"  # as Chart II-5 prints it


# ----------------------------------------------------------------------------- (c) Monte Carlo

DRAWS = 200


@pytest.fixture(scope="module")
def monte_carlo():
    ns = NoiseSpec()
    rng = np.random.default_rng(20240611)
    truth = TRUTH.expected()
    errors = {r: [] for r in truth}
    first = None
    for _ in range(DRAWS):
        data = make_data(rng, ns)
        first = first or data
        est = estimate(reduce(data).values, data.constants)
        for r, v in truth.items():
            errors[r].append(est[r] - v)
    _, sig = predicted_sigmas(first, ns)
    return {r: (np.array(e), sig[r]) for r, e in errors.items()}


def test_monte_carlo_scatter_matches_predicted_sigma(monte_carlo):
    ratios = {r: float(np.sqrt(np.mean(e**2)) / s) for r, (e, s) in monte_carlo.items()}
    bad = {r: round(x, 3) for r, x in ratios.items() if not 0.8 <= x <= 1.25}
    assert not bad, bad


# ----------------------------------------------------------------------------- pieces


def test_noise_spec_defaults_follow_the_default_config():
    ns, g, env = NoiseSpec(), CFG["isu"]["gyros"][0], CFG["environment"]
    assert ns.gyro_arw_deg_rt_hr == g["arw_deg_rt_hr"]
    assert ns.gyro_drift_sigma_deg_hr == g["drift_sigma_deg_hr"]
    assert ns.gyro_drift_tau_s == g["drift_tau_s"]
    assert ns.gyro_sample_rate_hz == g["pulse_rate_hz"]
    assert ns.accel_white_micro_g_rt_hz == CFG["isu"]["accels"][0]["noise_micro_g_rt_hz"]
    assert ns.tilt_diurnal_pp_arcsec == env["pier_tilt"]["diurnal_pp_arcsec"]
    assert ns.tilt_diurnal_azimuth_deg == env["pier_tilt"]["diurnal_azimuth_deg"]
    assert ns.tilt_wander_sigma_arcsec == env["pier_tilt"]["wander_sigma_arcsec"]
    assert ns.tilt_wander_tau_s == env["pier_tilt"]["wander_tau_s"]
    assert ns.wobble_amplitude_arcsec == env["wobble"]["amplitude_arcsec"]
    assert ns.wobble_period_s == env["wobble"]["period_s"]
    assert ns.wobble_coherence_s == env["wobble"]["coherence_s"]
    assert ns.table_setting_arcsec == CFG["table"]["setting_noise_arcsec"]
    assert ns.resolver_cyclic_arcsec == CFG["table"]["resolver_error_arcsec"]
    assert ns.nonorthogonality_arcsec == CFG["table"]["nonorthogonality_arcsec"]
    assert ns.bubble_noise_arcsec == CFG["instruments"]["bubble_level"]["noise_arcsec"]
    assert ns.bubble_graduation_arcsec == CFG["instruments"]["bubble_level"]["resolution_arcsec"]
    assert ns.autocollimator_arcsec == CFG["instruments"]["autocollimator"]["noise_arcsec"]
    assert ns.oscillator_drift_per_day == abs(CFG["oscillator"]["drift_per_day"])


def brute(fs: list[Functional], kernel) -> np.ndarray:
    """Gram matrix by dense quadrature (0.5 s midpoint grid: about 1e-5 relative)."""

    def samples(f: Functional):
        out = []
        for w, a, b in f.atoms:
            if a == b:
                out.append((np.array([a]), np.array([w])))
            else:
                t = np.arange(a + 0.25, b, 0.5)
                out.append((t, np.full(t.size, w / t.size)))
        return out

    n = len(fs)
    g = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            for ti, wi in samples(fs[i]):
                for tj, wj in samples(fs[j]):
                    g[i, j] += wi @ kernel(ti[:, None] - tj[None, :]) @ wj
    return g


def test_kernels_against_quadrature():
    fs = [
        Functional.point(1200.0, 1 / 600) + Functional.point(600.0, -1 / 600),
        Functional.mean(0.0, 1800.0, 0.5) + Functional.mean(0.0, 1700.0, 0.5),
        Functional.mean(2000.0, 2600.0) + Functional.point(1900.0, -1.0),
    ]
    g = exp_gram(fs, 900.0)
    np.testing.assert_allclose(g, brute(fs, lambda x: np.exp(-np.abs(x) / 900.0)), atol=1e-6)
    f, w = band_nodes(1 / 60 - 1 / 1200, 1 / 60 + 1 / 1200, 2600.0)

    def wobble(x):
        return np.cos(2 * math.pi * x / 60) * np.sinc(x / 600)

    np.testing.assert_allclose(cosine_gram(fs, f, w), brute(fs, wobble), rtol=1e-5, atol=2e-6)
    ee, nn, en = NoiseSpec().tilt_covariance(np.array([0.0, 300.0]))
    assert ee[0] > nn[0] > 0 and en[0] > 0 and ee[1] < ee[0]


def test_accel_keys_round_trip_through_json():
    p = NOISE_FREE.accel[7]
    assert AccelPosition.model_validate_json(p.model_dump_json()) == p


def test_a_datum_moves_only_the_instruments_that_read_it():
    """constants_covariance re-estimates only ``readers(key)`` per datum; every other
    instrument's constants must come out bit-identical when the datum moves."""
    from procedures.isu.calibration.compute import INSTRUMENTS, estimate_of, readers

    data = make_data(np.random.default_rng(7), NoiseSpec())
    z0 = reduce(data).values
    c = data.constants
    base = {inst: estimate_of(z0, c, inst) for inst in INSTRUMENTS}
    moved = 0
    for key, v in z0.items():
        z = dict(z0)
        z[key] = v * (1.0 + 1e-3) + 1e-6
        for inst in INSTRUMENTS:
            if inst in readers(key):
                moved += estimate_of(z, c, inst) != base[inst]
            else:
                assert estimate_of(z, c, inst) == base[inst], (key, inst)
    assert moved > len(z0) // 2  # the rule is not vacuous: the readers do move



def test_a_held_covariance_is_the_one_its_inputs_give():
    """constants_covariance hands out a held result only for inputs of the same content: the
    same bits as a fresh computation, a copy the caller may change, and a count moved by
    one (or a louder gyro) computed anew."""
    from procedures.isu.calibration import compute

    data = make_data(np.random.default_rng(11), NoiseSpec())
    compute._HELD.clear()
    est, rows, cov = compute.constants_covariance(data, NoiseSpec())
    f_rows, f_cov, prop = compute._constants_covariance(data, NoiseSpec())
    fresh = (prop.est, f_rows, f_cov)
    assert est == fresh[0] and rows == fresh[1] and np.array_equal(cov, fresh[2])
    cov[0, 0] = -1.0  # the caller's copy
    est[rows[0]] = None
    again = compute.constants_covariance(data.model_copy(deep=True), NoiseSpec())
    assert again[0] == fresh[0] and np.array_equal(again[2], fresh[2])
    # what the residual check reads from it: each datum moved by +-h, its readers'
    # estimates as estimate_of gives them there
    red = reduce(data)
    assert prop.keys == list(red.values)
    for i in np.random.default_rng(3).choice(len(prop.keys), 8, replace=False):
        key, h = prop.keys[i], prop.steps[i]
        for sign in (1, -1):
            z = dict(red.values)
            z[key] = red.values[key] + sign * h
            want: dict = {}
            for inst in compute.readers(key):
                want.update(compute.estimate_of(z, data.constants, inst))
            assert prop.moved[(int(i), sign)] == want
    m = max(data.gyro)  # a static position: gyro 1's count one more
    pos = data.gyro[m]
    delta = (pos.delta[0] + 1.0, *pos.delta[1:])
    nudged = data.model_copy(update={"gyro": {**data.gyro, m: pos.model_copy(
        update={"delta": delta})}})
    assert compute.constants_covariance(nudged, NoiseSpec())[0] != fresh[0]
    louder = NoiseSpec(gyro_arw_deg_rt_hr=2.0 * NoiseSpec().gyro_arw_deg_rt_hr)
    assert not np.array_equal(compute.constants_covariance(data, louder)[2], fresh[2])
