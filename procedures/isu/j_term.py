"""II-1.3 J term experiment (Chart II-10, left blank in report 000): designed here.

Design (docs/special-experiments.md): with the rotary axis up and a gyro's output axis O along it
(position 7 for gyros 2 and 3, whose O = B1; position 11 for gyro 1, O = B3), the J term
adds J * delta(w.O) to the gyro's angle over a gate: J times the change of the table rate,
whatever the acceleration profile. Two gates of equal length are taken back to back:
"up" (from rest, ramp at a commanded acceleration to w1) and "down" (from w1 back to rest).
Their difference keeps 2 J w1 and cancels every constant term (bias, g-terms). What remains
is computed from the table's commanded motion: the table rate seen through the input-axis
misalignment (G.R1)(theta_up - theta_down), and the Earth's horizontal rate seen by the
turning input axis, W sin(lambda) [(G.R2) int sin(phi2) dt + (G.R3) int cos(phi2) dt]:
the integrals of sin phi2 and cos phi2 that II-1.3 anticipates.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from procedures.isu.calibration.covariance import tilt_grams
from procedures.isu.calibration.kernels import Functional, exp_gram
from procedures.isu.calibration.noise_spec import ARCSEC, NoiseSpec
from procedures.isu.common import patch, set_modes, set_position
from procedures.isu.plan import DayPlan
from procedures.isu.plausibility import Implausible, guarded, source_of
from procedures.isu.readings import resolver
from procedures.isu.settings import GYRO_STATIC, wiring
from procedures.isu.sheets import ResolverSettings
from procedures.runner import Run

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

TITLE = "J term experiment (designed: commanded table acceleration, positions 7 and 11)"
GYROS_OF_POSITION = {7: (2, 3), 11: (1,)}
# the table's rotary angle after a gate against the commanded ramp: a few arcsec of
# resolver error and servo lag on a good day, plus the turn during a link's delay when the
# table still turns (a real-time link: up to PROFILE_DELAY_S); a stalled axis is far off
PROFILE_TOLERANCE_DEG = 0.01
PROFILE_DELAY_S = 0.05
DEG = math.pi / 180.0


@dataclass(frozen=True)
class RampProfile:
    """phi2(t) in deg (t from the reading phi0) for a ramp from rate w0 to w1 (deg/s) at
    |acc| commanded at t_cmd: a line, a parabola, a line (``breaks`` between them)."""

    phi0_deg: float
    w0: float
    w1: float
    acc: float
    t_cmd: float

    @property
    def t_ramp(self) -> float:
        return abs(self.w1 - self.w0) / self.acc

    @property
    def breaks(self) -> tuple[float, float]:
        return self.t_cmd, self.t_cmd + self.t_ramp

    def __call__(self, t: float) -> float:
        a = math.copysign(self.acc, self.w1 - self.w0)
        w0, t_cmd, t_ramp = self.w0, self.t_cmd, self.t_ramp
        if t <= t_cmd:
            return self.phi0_deg + w0 * t
        dt = t - t_cmd
        if dt <= t_ramp:
            return self.phi0_deg + w0 * t_cmd + w0 * dt + 0.5 * a * dt * dt
        return (self.phi0_deg + w0 * t_cmd + w0 * t_ramp + 0.5 * a * t_ramp**2
                + self.w1 * (dt - t_ramp))


def profile(phi0_deg: float, w0: float, w1: float, acc: float, t_cmd: float) -> RampProfile:
    """The commanded phi2(t) of one gate (``RampProfile``)."""
    return RampProfile(phi0_deg, w0, w1, acc, t_cmd)


GAUSS_NODES = 32  # per smooth piece: sin and cos of a phase sweeping a few radians, to 1e-15
_GAUSS = np.polynomial.legendre.leggauss(GAUSS_NODES)


def gate_integrals(phi: Callable[[float], float], t0: float,
                   t1: float) -> tuple[float, float, float]:
    """theta (deg), int sin(phi2) dt, int cos(phi2) dt over [t0, t1] (times relative):
    Gauss-Legendre on each smooth piece of the profile (split at its ``breaks``)."""
    cuts = [t0, *sorted(b for b in getattr(phi, "breaks", ()) if t0 < b < t1), t1]
    x, w = _GAUSS
    s = c = 0.0
    for lo, hi in zip(cuts[:-1], cuts[1:], strict=True):
        half, mid = 0.5 * (hi - lo), 0.5 * (hi + lo)
        ang = np.array([phi(float(t)) for t in mid + half * x]) * DEG
        s += half * float(w @ np.sin(ang))
        c += half * float(w @ np.cos(ang))
    return phi(t1) - phi(t0), s, c


def j_experiment(st: IsuDrivers, run: Run, settings: ResolverSettings, plan: DayPlan, s1: float,
                 pairs: int = 4, gate_s: float = 20.0) -> dict:
    """Run the up/down gates in positions 7 and 11; return the raw records per position.

    The ramp starts at gate_s/2 - t_ramp/2 into each gate, so the two gates of a pair turn
    the table through the same angle: the input-axis misalignment term (G.R1) theta then
    cancels in the difference, and J does not depend on how well G.R1 is known.
    """
    w1, acc = plan.j_rate_deg_s, plan.j_accel_deg_s2
    lead_s = 0.5 * (gate_s - w1 / acc)
    n_ticks = int(round(gate_s / s1))
    out: dict[int, list[dict]] = {}
    with run.sheet("II-10", TITLE) as sheet:
        sheet.done("1", "Scale factors and (Q^G)^-1 known (Chart II-6); survey done")
        with sheet.step("2", "Patch gyros and master oscillator to counters 2-4 (positions "
                        "7-15 wiring); measure Z"):
            patch(st, wiring(GYRO_STATIC))
            set_modes(st, (2, 3, 4), "measure Z")
        for m, gyros in GYROS_OF_POSITION.items():
            p = settings.positions[str(m)]
            tag = f"/m{m}"
            with sheet.step("3" + tag, f"Set position {m} with level correction; table at "
                            "rest") as s:
                ps = set_position(st, 0.0, 90.0, p.phi3, p.phi4, level=True)
                s.reading = ps.reading()
            counters = {k + 1: n_ticks for k in gyros}
            recs = []
            for i in range(pairs):
                for direction in ("up", "down"):
                    t_tag = f"{tag}/{i + 1}{direction}"
                    with sheet.step("4" + t_tag, f"Gate '{direction}': operate, then after "
                                    f"{lead_s:g} s ramp the rate at {acc:g} deg/s^2") as s:
                        w_start = 0.0 if direction == "up" else w1
                        w_end = w1 if direction == "up" else 0.0
                        for c, n in counters.items():
                            st.counters[c].set_preset(n)
                            st.counters[c].discard_readings()
                        t_pos = st.clock.now()  # the resolver is sampled when asked
                        phi_start = resolver(st, 2)
                        t_oper = {}
                        for c in counters:
                            t_oper[c] = st.clock.now() - t_pos
                            st.counters[c].operate()
                        st.clock.sleep(lead_s - (st.clock.now() - t_pos))
                        t_cmd = st.clock.now() - t_pos
                        st.table.ramp(2, acc, w_end)
                        readings = {c: st.counters[c].read(timeout=gate_s * 3 + 30)
                                    for c in counters}
                        for c in counters:
                            st.counters[c].standby()
                        t_read = st.clock.now() - t_pos
                        phi_read = resolver(st, 2)
                        prof = profile(phi_start, w_start, w_end, acc, t_cmd)
                        off = (prof(t_read) - phi_read + 180.0) % 360.0 - 180.0
                        if abs(off) > PROFILE_TOLERANCE_DEG + abs(w_end) * PROFILE_DELAY_S:
                            rate = guarded(st.table, "axis 2 rate", lambda: st.table.rate(2))
                            raise Implausible(
                                source_of(st.table),
                                f"axis 2 did not follow the commanded ramp: it reads "
                                f"{phi_read:.4f} deg where the ramp from {phi_start:.4f} deg "
                                f"puts it at {prof(t_read) % 360.0:.4f} deg (RATE? "
                                f"{rate:g} deg/s, commanded {w_end:g})")
                        rec = {"direction": direction, "t_pos_s": t_pos, "phi_start": phi_start,
                               "w_start": w_start, "w_end": w_end, "t_cmd": t_cmd,
                               "gate_s": n_ticks * s1,
                               "t_oper": {str(c): v for c, v in t_oper.items()},
                               "counts": {str(c): v for c, v in readings.items()},
                               "phi_check_deg": off}
                        recs.append(rec)
                        s.reading = rec
            with sheet.step("5" + tag, "Stop the table"):
                st.table.stop(2)
                st.table.wait_still()
            out[m] = recs
    return out


@dataclass(frozen=True)
class JNoise:
    """The error sources of one gyro's J gates (docs/special-experiments.md).

    Counts: quantization ``quantization_var`` (pulses^2 per count, a difference of two
    floors); the floors of the end of one gate and the start of the next are read a few tens
    of ms apart, so they share the gyro's fractional phase unless it advanced meanwhile: the
    two counts' errors correlate by -(q/2)(1 - 6 d(1 - d)), d the fractional advance (rest rate
    ``rest_rate_deg_hr`` besides the Earth's horizontal rate and the table rate through G.R1).
    Taken as independent, the chain of back-to-back gates made the predicted sigma about
    1.3x optimistic where quantization dominates (0.3x noise). ``white_var`` (pulses^2 per
    gate): angle random walk. Random drift (``drift_deg_hr``, Gauss-Markov over
    ``drift_tau_s``): nearly the same in the two gates of a pair, so it cancels in their
    difference instead of adding per gate. The pier's tilt (``pier``): the horizontal input
    axis, turning with the table, sees int tilt_rate . G(t) dt (``tilt_functionals``), with
    the pier's covariance across the gates; taken per gate as the full tilt change (both
    horizontal axes, ``tilt_var``: the fallback for records without gate times) it was
    about 1.4x pessimistic where the tilt dominates. The up and down gates of a pair share
    most of the wobble (their tilt angles correlate about +0.8): the quantization chain's
    correlation adds to that, it does not replace it (i19j).
    """

    quantization_var: float
    white_var: float
    drift_deg_hr: float
    drift_tau_s: float
    rest_rate_deg_hr: float = 0.0
    tilt_var: float = 0.0
    pier: NoiseSpec | None = None


def _gate_times(rec: dict, counter: int) -> tuple[float, float] | None:
    """Absolute (start, end) of a gate, s; None for a record made before they were kept."""
    if "t_pos_s" not in rec:
        return None
    t0 = rec["t_pos_s"] + rec["t_oper"][str(counter)]
    return t0, t0 + rec["gate_s"]


TILT_STEP_S = 0.5  # sub-interval of the tilt functionals: G turns 5 deg in it at 10 deg/s


def tilt_functionals(rec: dict, counter: int, g_r: np.ndarray, accel: float
                     ) -> tuple[Functional, Functional]:
    """(east, north) functionals of the tilt whose sum is the angle (rad) a gate's gyro sees:
    int tilt_rate . G dt = [tilt . G] at the ends - int tilt . dG/dt dt, G's horizontal
    part turning with the table: (G_E, G_N) = (g2 cos phi - g3 sin phi, g2 sin phi
    + g3 cos phi), phi the rotary angle of the commanded profile."""
    prof = profile(rec["phi_start"], rec["w_start"], rec["w_end"], accel, rec["t_cmd"])
    t0 = rec["t_oper"][str(counter)]
    t1 = t0 + rec["gate_s"]
    base = rec["t_pos_s"]

    def g_en(t: float) -> tuple[float, float]:
        p = prof(t) * DEG
        return (g_r[1] * math.cos(p) - g_r[2] * math.sin(p),
                g_r[1] * math.sin(p) + g_r[2] * math.cos(p))

    (e0, n0), (e1, n1) = g_en(t0), g_en(t1)
    fe = Functional.point(base + t1, e1) + Functional.point(base + t0, -e0)
    fn = Functional.point(base + t1, n1) + Functional.point(base + t0, -n0)
    k = max(1, int(math.ceil((t1 - t0) / TILT_STEP_S)))
    edges = np.linspace(t0, t1, k + 1)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        (ea, na), (eb, nb) = g_en(float(a)), g_en(float(b))
        fe = fe + Functional.mean(base + a, base + b, -(eb - ea))
        fn = fn + Functional.mean(base + a, base + b, -(nb - na))
    return fe, fn


def tilt_covariance(records: list[dict], counter: int, dphi_arcsec: float, g_r: np.ndarray,
                    accel: float, pier: NoiseSpec) -> np.ndarray:
    """Covariance (pulses^2) of the gates' tilt angles (``tilt_functionals``) under the
    pier's diurnal tilt, wander and wobble (``NoiseSpec``): the Grams of
    ``calibration.covariance.tilt_grams``, as the calibration's fits take them."""
    n = len(records)
    pairs = [tilt_functionals(r, counter, g_r, accel) for r in records]
    fs = tuple([e for e, _ in pairs] + [x for _, x in pairs])
    diurnal, wander, wobble = tilt_grams(fs, pier)
    iso = wander + wobble
    az = math.radians(pier.tilt_diurnal_azimuth_deg)
    E, N = slice(0, n), slice(n, 2 * n)
    c, s_ = math.cos(az), math.sin(az)
    rad = (diurnal[E, E] * c * c + diurnal[N, N] * s_ * s_
           + (diurnal[E, N] + diurnal[N, E]) * c * s_ + iso[E, E] + iso[N, N])
    return rad * (1.0 / ARCSEC / dphi_arcsec) ** 2


def gate_covariance(records: list[dict], counter: int, dphi_arcsec: float, g_r: np.ndarray,
                    omega_sin_lambda: float, accel: float, noise: JNoise) -> np.ndarray:
    """Covariance (pulses^2) of the count errors of the gates in ``records`` (``JNoise``)."""
    n = len(records)
    q = noise.quantization_var
    cov = np.eye(n) * (q + noise.white_var)
    times = [_gate_times(r, counter) for r in records]
    if any(t is None for t in times):  # older records: gates taken as independent
        drift = (noise.drift_deg_hr * records[0]["gate_s"] / dphi_arcsec) ** 2
        return cov + np.eye(n) * (drift + noise.tilt_var)
    spans = [t for t in times if t is not None]
    fs = [Functional.mean(a, b, (b - a) / dphi_arcsec) for a, b in spans]
    cov += exp_gram(fs, noise.drift_tau_s) * noise.drift_deg_hr**2
    if noise.pier is not None:
        cov += tilt_covariance(records, counter, dphi_arcsec, g_r, accel, noise.pier)
    else:
        cov += np.eye(n) * noise.tilt_var
    for j in range(n - 1):
        rec = records[j]
        prof = profile(rec["phi_start"], rec["w_start"], rec["w_end"], accel, rec["t_cmd"])
        t_end = rec["t_oper"][str(counter)] + rec["gate_s"]
        phi = prof(t_end) * DEG
        rate = (g_r[0] * rec["w_end"] * 3600.0 + noise.rest_rate_deg_hr
                + omega_sin_lambda * (g_r[1] * math.sin(phi) + g_r[2] * math.cos(phi)))
        gap = spans[j + 1][0] - spans[j][1]
        d = (abs(rate) * gap / dphi_arcsec) % 1.0
        c = 0.5 * q * (1.0 - 6.0 * d * (1.0 - d))
        # added to the drift's and the tilt's covariance of the two gates, not in place of
        # it: a pair's up and down gates share most of the pier's wobble (issue 19, i19j)
        cov[j, j + 1] -= c
        cov[j + 1, j] -= c
    return cov


def _pair_js(records: list[dict], counter: int, dphi_arcsec: float, g_r: np.ndarray,
             omega_sin_lambda: float, accel: float) -> tuple[list[float], list[float]]:
    """Each up/down pair's J (hours) and the weight w of its counts: J = w (up - down)."""
    dphi = dphi_arcsec / 3600.0  # deg per pulse
    w_sin = omega_sin_lambda / 3600.0  # deg/s
    js, ws = [], []
    for up, down in zip(records[0::2], records[1::2], strict=True):
        terms = []
        for rec in (up, down):
            prof = profile(rec["phi_start"], rec["w_start"], rec["w_end"], accel, rec["t_cmd"])
            t0 = rec["t_oper"][str(counter)]  # the gate opens on the next clock tick
            theta, s_int, c_int = gate_integrals(prof, t0, t0 + rec["gate_s"])
            angle = rec["counts"][str(counter)] * dphi  # deg
            # remove what is not J: table rate through G.R1, Earth's horizontal rate
            known = g_r[0] * theta + w_sin * (g_r[1] * s_int + g_r[2] * c_int)
            terms.append(angle - known)
        dw = up["w_end"] - up["w_start"] - (down["w_end"] - down["w_start"])  # deg/s
        js.append((terms[0] - terms[1]) / dw / 3600.0)  # deg / (deg/s) = s -> hours
        ws.append(dphi / dw / 3600.0)
    return js, ws


def j_estimate(records: list[dict], counter: int, dphi_arcsec: float, g_r: np.ndarray,
               omega_sin_lambda: float, accel: float, noise: JNoise) -> tuple[float, float]:
    """J (hours) and its sigma from the up/down gate pairs of one gyro (``j_result``).

    g_r: the gyro's input axis in rotary-frame components (G.R1, G.R2, G.R3); the rotary
    frame at phi2 has R2 = cos(phi2) E + sin(phi2) N, R3 = -sin(phi2) E + cos(phi2) N.
    """
    j, sigma, _ = j_result(records, counter, dphi_arcsec, g_r, omega_sin_lambda, accel, noise)
    return j, sigma


def j_result(records: list[dict], counter: int, dphi_arcsec: float, g_r: np.ndarray,
             omega_sin_lambda: float, accel: float, noise: JNoise
             ) -> tuple[float, float, list[float]]:
    """J (hours), its sigma, and each up/down pair's J against the others' mean in units
    of its sigma (the pairs are independent measurements of one J; a garbled count makes
    one pair stand out): the pairs' J and the gates' covariance computed once for both."""
    js, ws = _pair_js(records, counter, dphi_arcsec, g_r, omega_sin_lambda, accel)
    pairs = len(js)
    cov = gate_covariance(records[: 2 * pairs], counter, dphi_arcsec, g_r, omega_sin_lambda,
                          accel, noise)
    weights = np.zeros(2 * pairs)
    for i, w in enumerate(ws):
        weights[2 * i: 2 * i + 2] = np.array([1.0, -1.0]) * w / pairs
    sigma = math.sqrt(max(float(weights @ cov @ weights), 0.0))
    return float(np.mean(js)), sigma, _pair_z(js, ws, cov)


def _pair_z(js_: list[float], ws: list[float], cov: np.ndarray) -> list[float]:
    """Each pair's J against the others' mean in units of its sigma (from its 2 x 2 block of
    the gates' covariance); none with fewer than three pairs."""
    var = []
    for i, w in enumerate(ws):
        b = cov[2 * i: 2 * i + 2, 2 * i: 2 * i + 2]
        v = np.array([w, -w])
        var.append(max(float(v @ b @ v), 0.0))
    js = np.array(js_)
    sig = float(np.sqrt(np.mean(var))) if var else 0.0
    n = len(js)
    if n < 3 or not sig > 0:
        return []
    others = (js.sum() - js) / (n - 1)
    return [float(x) for x in (js - others) / (sig * math.sqrt(1.0 + 1.0 / (n - 1)))]
