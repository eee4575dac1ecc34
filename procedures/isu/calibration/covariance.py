"""Error covariance of the reduced data (``reduce``) from the lab's NoiseSpec and geometry.

Per datum (rates in pulses/s; gate T = n1 S1^T):
* gyro counts: quantization q (1 + (rho/f_s)^2) / T^2, the count being a difference of two
  floors read at the rebalance loop's sampling instants (f_s the sampling rate); with the
  sampling clock known against the counter's (``NoiseSpec.gyro_sample_clock_ppm``) the
  edges' sampling offsets differ by frac(T f_s) and (rho/f_s)^2 takes E[c (1 - c)]
  (``quantization``: zero for a gate of whole sampling periods); with
  II-5.2's pulse gate (a preset of gyro pulses, the clock counted) the count is exact and
  the gate's two edges fall on sampling instants: rho^2 (q_clk / n1^2 + 1 / (6 f_s^2 T^2));
  angle
  random walk N^2 (T/3600) / (DeltaPhi^2 T^2); random drift: gate means of a Gauss-Markov
  process, correlated between the positions of one gyro through exp(-|dt|/tau);
* table rate and turning gyro rates share counter 1's clock count n1 (quantization q_clk):
  w, rho_1..3 of one position are correlated through it;
* pier tilt: a gyro sees the tilt change over its gate, rate error
  (eps(t1) - eps(t0)) . h / T with h the horizontal earth components of its G (turning:
  only the part along the turning axis R1 = south survives whole turns); a level-corrected
  accelerometer sees the gate mean of the tilt minus the tilt at the bubble reading,
  D1 g [X_E (A.n) + X_N A.(u x n)] (u, n body up and north), each string over its own gate;
  the tilt covariance (east, north, cross) is that of ``NoiseSpec.tilt_covariance``;
* accelerometer white noise q on f2 - f1: each string averages it over its own gate,
  F = (D1/2)(mean_1 + mean_2); clock quantization q_clk per string count; floor vibration
  (velocity change over the gate, independent per gate; negligible);
* orientation: each setting's body rotation Delta (``geometry.TableErrorModel``), carried
  into the data by the forward model (``forward``) at the estimated coefficients;
* a supplied last (D1 D3) or [(G.B)/DeltaPhi] of an earlier sheet: its stated sigma;
* the master oscillator: every rate above is counted against it (S1^T), so an offset e of
  its frequency from the nominal the lab records (Chart I-1 step 3) puts every one off by
  -e times itself together, a rank-one term (``NoiseSpec.oscillator_frequency_error`` as
  e's sigma); a supplied datum is not counted here.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from procedures.isu.calibration.forward import AccelModel, GyroModel
from procedures.isu.calibration.geometry import FIRST_COLUMN, SettingKey, TableErrorModel
from procedures.isu.calibration.inputs import Constants
from procedures.isu.calibration.kernels import (
    ZERO,
    Functional,
    band_nodes,
    cosine_gram,
    exp_gram,
)
from procedures.isu.calibration.noise_spec import ARCSEC, DAY, NoiseSpec
from procedures.isu.calibration.quantization import edge_sampling_var
from procedures.isu.calibration.reduce import Key, Record, Reduced
from procedures.isu.calibration.vectors import cross3

RAD2DEG = 180.0 / math.pi


def gyro_quantization_var(rate: float, rec: Record, nz: NoiseSpec) -> float:
    """Variance (pulses/s)^2 of a gyro rate from the counter's quantization: a clock gate
    reads the count to a pulse and each edge's phase at the last sampling instant (the two
    edges' sampling offsets correlated when the sampling clock is known against the
    counter's: ``quantization.edge_sampling_var``); a pulse gate (II-5.2) reads the time
    to a clock tick and to a sampling period at each edge."""
    tau_s = 1.0 / nz.gyro_sample_rate_hz
    T = rec.length
    if rec.pulse_gate:
        return rate**2 * (nz.clock_quantization_var / rec.n1**2 + tau_s**2 / (6.0 * T**2))
    if nz.gyro_sample_clock_ppm is None:  # the edges independent: q for the sampling too
        return nz.count_quantization_var * (1.0 + (rate * tau_s) ** 2) / T**2
    edges = edge_sampling_var(T, rec.n1, nz.gyro_sample_rate_hz, nz.gyro_sample_clock_ppm,
                              nz.clock_quantization_var)
    return (nz.count_quantization_var + edges * (rate * tau_s) ** 2) / T**2


@lru_cache(maxsize=4)
def tilt_grams(fs: tuple[Functional, ...], nz: NoiseSpec
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gram matrices (rad^2) of the tilt functionals ``fs`` under the diurnal term, the
    wander and the wobble of ``nz``. They depend on the gates' times only, so the fits of
    one day's data share them (issue 17: 3 covariances of the same records, 12 ms each,
    most of it the wobble band's transforms); read-only, as the cache shares them. The J
    experiment's tilt covariance takes its Grams here too."""
    times = [t for f in fs for _, a, b in f.atoms for t in (a, b)]
    span = (max(times) - min(times)) if times else 0.0
    amp = 0.5 * nz.tilt_diurnal_pp_arcsec * ARCSEC
    diurnal = cosine_gram(fs, np.array([1.0 / DAY]), np.array([1.0])) * 0.5 * amp * amp
    wander = exp_gram(fs, nz.tilt_wander_tau_s) * (nz.tilt_wander_sigma_arcsec * ARCSEC) ** 2
    fb, df = 1.0 / nz.wobble_period_s, 1.0 / nz.wobble_coherence_s
    nodes, weights = band_nodes(fb - 0.5 * df, fb + 0.5 * df, span)
    b = nz.wobble_amplitude_arcsec * ARCSEC
    wobble = cosine_gram(fs, nodes, weights) * 0.5 * b * b
    for g in (diurnal, wander, wobble):
        g.setflags(write=False)
    return diurnal, wander, wobble


def setting_of(key: Key) -> SettingKey | None:
    kind, _, m = key
    if kind == "G":
        return ("R", m) if m <= 6 else ("G", m)
    if kind == "F":
        return ("A", m)
    return None


class DataCovariance:
    """Builds the covariance matrix of ``red`` in the order of ``keys``."""

    def __init__(
        self,
        red: Reduced,
        keys: list[Key],
        c: Constants,
        noise: NoiseSpec,
        gyros: dict[int, GyroModel],
        accels: dict[int, AccelModel],
        table: TableErrorModel,
        t_br: dict[SettingKey, np.ndarray],
    ) -> None:
        self.red, self.keys, self.c, self.noise = red, keys, c, noise
        self.gyros, self.accels, self.table, self.t_br = gyros, accels, table, t_br
        self.index = {k: i for i, k in enumerate(keys)}

    # ----- pieces -----
    def independent(self) -> np.ndarray:
        nz = self.noise
        n = len(self.keys)
        out = np.zeros((n, n))
        q_clk = nz.clock_quantization_var
        by_position: dict[int, list[int]] = {}
        for i, key in enumerate(self.keys):
            rec = self.red.records[key]
            val = self.red.values[key]
            kind, k, m = key
            if kind in ("X", "P"):
                out[i, i] += rec.sigma**2
            elif kind == "w":
                by_position.setdefault(m, []).append(i)
            elif kind == "G":
                T = rec.length
                dphi = self.gyros[k].dphi_deg
                out[i, i] += gyro_quantization_var(val, rec, nz)
                out[i, i] += nz.gyro_arw_deg_rt_hr**2 * (T / 3600.0) / (dphi * T) ** 2
                if m <= 6:
                    by_position.setdefault(m, []).append(i)
            elif kind == "F":
                (f1, n11, T1), (f2, n12, T2) = rec.strings
                d1 = self.accels[k].D1
                q = (nz.accel_white_micro_g_rt_hz * 1e-6) ** 2
                out[i, i] += d1 * d1 * q * 0.25 * (1 / T1 + 1 / T2 + 2 / max(T1, T2))
                out[i, i] += q_clk * ((f1 / n11) ** 2 + (f2 / n12) ** 2)
                flo, fhi = nz.vibration_band_hz
                var_v = (nz.vibration_rms_micro_g * 1e-6) ** 2 / ((2 * math.pi) ** 2 * flo * fhi)
                out[i, i] += d1 * d1 * 2.0 * var_v / (0.5 * (T1 + T2)) ** 2
        # counter 1's clock count divides the table rate and the gyro rates of a position
        for idx in by_position.values():
            n1 = self.red.records[self.keys[idx[0]]].n1
            v = np.array([self.red.values[self.keys[i]] for i in idx])
            out[np.ix_(idx, idx)] += np.outer(v, v) * q_clk / n1**2
        return out

    def drift(self) -> np.ndarray:
        nz = self.noise
        n = len(self.keys)
        out = np.zeros((n, n))
        for k, gm in self.gyros.items():
            idx = [i for i, key in enumerate(self.keys) if key[0] == "G" and key[1] == k]
            if not idx:
                continue
            fs = []
            for i in idx:
                rec = self.red.records[self.keys[i]]
                fs.append(Functional.mean(rec.t0, rec.t0 + rec.length, 1.0 / (3600 * gm.dphi_deg)))
            gram = exp_gram(fs, nz.gyro_drift_tau_s) * nz.gyro_drift_sigma_deg_hr**2
            out[np.ix_(idx, idx)] += gram
        return out

    def _tilt_terms(self) -> tuple[list[Functional], np.ndarray, np.ndarray]:
        """Per datum: the tilt functional and its east and north coefficients."""
        fs, he, hn = [], [], []
        for key in self.keys:
            rec = self.red.records[key]
            kind, k, m = key
            f, e, n = ZERO, 0.0, 0.0
            if kind == "G":
                gm = self.gyros[k]
                T = rec.length
                f = Functional.point(rec.t0 + T, 1.0 / T) + Functional.point(rec.t0, -1.0 / T)
                to_pulses = RAD2DEG / gm.dphi_deg
                if m <= 6:
                    n = -float(gm.G @ FIRST_COLUMN[m]) * to_pulses  # R1 = south
                else:
                    t = self.t_br[("G", m)]
                    u, no = t[:, 0], t[:, 1]
                    e = -float(gm.G @ cross3(u, no)) * to_pulses
                    n = float(gm.G @ no) * to_pulses
            elif kind == "F":
                am = self.accels[k]
                (_, _, T1), (_, _, T2) = rec.strings
                f = (
                    Functional.mean(rec.t0, rec.t0 + T1, 0.5)
                    + Functional.mean(rec.t0, rec.t0 + T2, 0.5)
                    + Functional.point(rec.t_level, -1.0)
                )
                t = self.t_br[("A", m)]
                u, no = t[:, 0], t[:, 1]
                s = am.D1 * self.c.g
                e, n = s * float(am.A @ no), s * float(am.A @ cross3(u, no))
            fs.append(f)
            he.append(e)
            hn.append(n)
        return fs, np.array(he), np.array(hn)

    def tilt(self) -> np.ndarray:
        nz = self.noise
        fs, he, hn = self._tilt_terms()
        diurnal, wander, wobble = tilt_grams(tuple(fs), nz)
        az = math.radians(nz.tilt_diurnal_azimuth_deg)
        ee = diurnal * math.cos(az) ** 2 + wander + wobble
        nn = diurnal * math.sin(az) ** 2 + wander + wobble
        en = diurnal * math.cos(az) * math.sin(az)
        return (
            np.outer(he, he) * ee
            + np.outer(hn, hn) * nn
            + (np.outer(he, hn) + np.outer(hn, he)) * en
        )

    def orientation_jacobian(self) -> tuple[np.ndarray, np.ndarray]:
        """d(data)/d(sources) and the sources' sigmas."""
        settings = sorted({s for key in self.keys if (s := setting_of(key)) is not None})
        maps = self.table.maps(settings, self.t_br)
        sig = self.table.sigmas
        out = np.zeros((len(self.keys), sig.size))
        h = 1e-6
        for i, key in enumerate(self.keys):
            s = setting_of(key)
            if s is None:
                continue
            grad = np.zeros(3)
            for j in range(3):
                d = np.zeros(3)
                d[j] = h
                grad[j] = (self._model(key, d) - self._model(key, -d)) / (2 * h)
            L = maps[s]
            out[i, : L.shape[1]] = grad @ L
        return out, sig

    def _model(self, key: Key, delta: np.ndarray) -> float:
        """Forward model of one datum with the setting's body turned by ``delta``."""
        kind, k, m = key

        def turn(v: np.ndarray) -> np.ndarray:
            return v - cross3(delta, v)

        if kind == "G" and m <= 6:
            w = self.red.values[("w", 0, m)]
            return self.gyros[k].turning_rate(turn(FIRST_COLUMN[m]), w, self.c)
        if kind == "G":
            t = self.t_br[("G", m)]
            return self.gyros[k].static_rate(turn(t[:, 0]), turn(t[:, 1]), self.c)
        t = self.t_br[("A", m)]
        return self.accels[k].difference(turn(t[:, 0]), self.c)

    def orientation(self) -> np.ndarray:
        """The settings' orientation errors carried into the data (``orientation_jacobian``)."""
        d, sig = self.orientation_jacobian()
        return (d * sig**2) @ d.T

    def geometric(self) -> np.ndarray:
        """The part of the covariance that turns the input axis: pier tilt and settings."""
        return self.tilt() + self.orientation()

    def clock(self) -> np.ndarray:
        """The master oscillator's offset from nominal: every counted rate off by the same
        fraction of itself (rank one)."""
        e = self.noise.oscillator_frequency_error
        u = np.array([-self.red.values[key] * e if key[0] in ("w", "G", "F") else 0.0
                      for key in self.keys])
        return np.outer(u, u)

    def matrix(self) -> np.ndarray:
        return self.independent() + self.drift() + self.geometric() + self.clock()
