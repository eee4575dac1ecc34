"""Chart II-15's constants against the counter data they did not need.

The closed forms of II-4.2 and II-4.3 use part of the data only (``check_residuals``). The
rest is redundant: the pair sums of the turning positions 1-6 (each gyro's bias and even
terms over whole turns, which the static positions 7-15 and the nonlinearity experiment
already fix) and each accelerometer's second horizontal pair (a second D1 D0). With the
constants computed, the forward model (``forward``) predicts every datum; a datum's
residual, in units of the residual's own sigma, must stay within ``K_RESULT``. That sigma
is the data covariance (``covariance``: noise, pier tilt, table errors) carried through the
residual's Jacobian (a datum the constants were solved from has none and is not judged),
plus Q_II and Q_IS (special experiments) at their sigmas. A disagreement names the counters
whose readings make the datum, the position and the chart.

The accelerometer charts count each string on its own counter, and the constants use only
the difference f2 - f1. The sum f1 + f2 (the strings' common frequency) is even in the
input, 2 f0 + 2 kappa u^2 for push-pull strings, so over the positions it must follow
a + b u + c u^2 (b allows for a mismatch of the strings) within the strings' noise
(``check_string_sums``): a garbled string count breaks it even where the difference has no
redundancy (the vertical pairs that fix D1, D2 and D3).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from procedures.isu.calibration.accel_equations import ACCEL_PARAMS
from procedures.isu.calibration.compute import (
    Row,
    data_covariance_model,
    estimate_of,
    propagation,
    readers,
)
from procedures.isu.calibration.forward import AccelModel, GyroModel
from procedures.isu.calibration.geometry import FIRST_COLUMN, t_br
from procedures.isu.calibration.gyro_equations import GYRO_PARAMS
from procedures.isu.calibration.inputs import TURNING_POSITIONS, CalibrationData, Constants
from procedures.isu.calibration.noise_spec import DAY, NoiseSpec
from procedures.isu.calibration.reduce import Key, reduce
from procedures.isu.plausibility import Implausible
from procedures.isu.sheets import ResultRow

K_RESULT = 6.0  # a residual this many of its sigmas off stops the computation
REDUNDANT = 0.3  # judged only where the residual keeps this fraction of the datum's sigma
SPECIAL = ("Q_II", "Q_IS")  # from the special experiments, not from these data


def _chart(kind: str, m: int) -> str:
    if kind == "F":
        return "II-13" if m <= 12 else "II-14"
    return "II-6" if m <= 6 else ("II-11" if m <= 12 else "II-12")


def counters_of(key: Key) -> str:
    """The counters whose readings make a datum (the patch of its chart, Chart II-2)."""
    kind, k, m = key
    if kind == "F":
        return f"counter{2 * k - 1} and counter{2 * k} (accelerometer {k}'s strings)"
    if m in TURNING_POSITIONS:
        return f"counter{k + 1} (gyro {k}) or counter1 (the gate's clock count)"
    return f"counter{k + 1} (gyro {k})"


def owner(key: Key) -> str:
    """The instrument a G or F datum belongs to."""
    kind, k, _ = key
    return f"gyro{k}" if kind == "G" else f"accel{k}"


def predictions(z: Mapping[Key, float], c: Constants, keys: list[Key],
                special: Mapping[Row, float],
                known: Mapping[Row, float | None] | None = None) -> np.ndarray:
    """Each datum in ``keys`` as the constants computed from ``z`` predict it. ``known``:
    those constants, already computed from ``z`` (at least every owner's of ``keys``)."""
    est: dict[Row, float | None] = {}
    if known is None:
        for inst in sorted({owner(key) for key in keys}):  # only the models these data need
            est.update(estimate_of(z, c, inst))
    else:
        est.update(known)
    est = {**est, **special}

    def sub(prefix: str) -> dict[str, float | None]:
        return {p: v for (inst, p), v in est.items() if inst == prefix}

    gyros = {k: GyroModel.from_estimates(k, sub(f"gyro{k}")) for k in (1, 2, 3)
             if any(key[0] == "G" and key[1] == k for key in keys)}
    accels = {k: AccelModel.from_estimates(k, sub(f"accel{k}")) for k in (1, 2, 3)
              if any(key[0] != "G" and key[1] == k for key in keys)}
    out = []
    for kind, k, m in keys:
        if kind == "G" and m in TURNING_POSITIONS:
            out.append(gyros[k].turning_rate(FIRST_COLUMN[m], z[("w", 0, m)], c))
        elif kind == "G":
            t = t_br(m, c)
            out.append(gyros[k].static_rate(t[:, 0], t[:, 1], c))
        else:
            out.append(accels[k].difference(t_br(m, c)[:, 0] if m > 12 else FIRST_COLUMN[m],
                                            c))
    return np.array(out)


def check_residuals(data: CalibrationData, rows: list[ResultRow],
                    noise: NoiseSpec | None = None, k: float = K_RESULT) -> dict:
    """Residuals of the redundant data (``z`` in sigma); Implausible beyond ``k``."""
    noise = noise or NoiseSpec.model_validate({})
    c = data.constants
    red = reduce(data)
    special = {(r.instrument, r.parameter): r.estimate for r in rows
               if r.parameter in SPECIAL and r.estimate is not None}
    try:  # the estimates, the data covariance and the moved data's estimates, as the
        # constants' covariance computed them (the same steps: the same bits)
        prop = propagation(data, noise)
    except (ValueError, KeyError):
        return {"judged": 0, "note": "too few positions for a prediction"}
    keys = prop.keys
    est0 = {**prop.est, **special}

    def complete(kind: str, k: int, m: int) -> bool:
        """The forward model of this datum has every constant it needs (a partial day,
        Chart II-16, leaves some out: those data are not judged)."""
        if kind == "F":
            return all(est0.get((f"accel{k}", p)) is not None for p in ACCEL_PARAMS)
        need = [p for p in GYRO_PARAMS if p not in ("Q_II", "Q_IS", "J")]
        if m in TURNING_POSITIONS:
            need += list(SPECIAL)  # (w.G)^2 at the turning rate: several deg/hr
        return all(est0.get((f"gyro{k}", p)) is not None for p in need)

    judged = [key for key in keys if key[0] in ("G", "F") and complete(*key)]
    if not judged:
        return {"judged": 0, "residuals": {}}
    sp_sigma = {(r.instrument, r.parameter): r.sigma or 0.0 for r in rows
                if r.parameter in SPECIAL and r.estimate is not None}
    try:
        pred = predictions(red.values, c, judged, special, prop.est)
    except (ValueError, KeyError):
        return {"judged": 0, "note": "too few positions for a prediction"}
    z0 = np.array([red.values[key] for key in keys])
    resid0 = np.array([red.values[key] for key in judged]) - pred
    cov, steps = prop.data_cov, prop.steps
    jac = np.zeros((len(judged), len(keys)))
    for i, h in enumerate(steps):
        # Only the data of the instruments that read this datum (and the datum itself)
        # move: the other residuals would come out identical, their differences zero.
        near = set(readers(keys[i]))
        idx = [j for j, key in enumerate(judged) if owner(key) in near or key == keys[i]]
        if not idx:
            continue
        moved = [judged[j] for j in idx]
        zp, zm = dict(red.values), dict(red.values)
        zp[keys[i]] = z0[i] + h
        zm[keys[i]] = z0[i] - h
        rp = np.array([zp[key] for key in moved]) - predictions(zp, c, moved, special,
                                                                prop.moved[(i, 1)])
        rm = np.array([zm[key] for key in moved]) - predictions(zm, c, moved, special,
                                                                prop.moved[(i, -1)])
        jac[idx, i] = (rp - rm) / (2.0 * h)
    var = np.einsum("ij,jk,ik->i", jac, cov, jac)
    for row, s in sp_sigma.items():  # Q_II, Q_IS at their sigmas (special experiments)
        if s:
            up = predictions(red.values, c, judged, {**special, row: special[row] + s},
                             prop.est)
            dn = predictions(red.values, c, judged, {**special, row: special[row] - s},
                             prop.est)
            var += (0.5 * (up - dn)) ** 2
    own = np.array([cov[keys.index(key), keys.index(key)] for key in judged])
    out: dict[str, dict] = {}
    worst = None
    for key, r, v, o in zip(judged, resid0, var, own, strict=True):
        if not (v > (REDUNDANT**2) * o and v > 0):
            continue  # the constants were solved from this datum: nothing to judge
        zz = float(r / math.sqrt(v))
        kind, kk, m = key
        name = f"{'gyro' if kind == 'G' else 'accel'}{kk} position {m}"
        out[name] = {"residual": float(r), "sigma": float(math.sqrt(v)), "z": zz}
        if worst is None or abs(zz) > abs(worst[1]):
            worst = (key, zz, float(r), float(math.sqrt(v)))
    if worst is not None and abs(worst[1]) > k:
        key, zz, r, s = worst
        kind, kk, m = key
        what = f"rate of gyro {kk}" if kind == "G" else f"f2 - f1 of accelerometer {kk}"
        raise Implausible(
            counters_of(key),
            f"Chart {_chart(kind, m)} position {m}: the {what} is {r:+.4g} pulses/s off what "
            f"the other positions' constants predict ({zz:+.1f} sigma, sigma {s:.3g} "
            f"pulses/s, limit {k:g}): a wrong count")
    return {"judged": len(out), "residuals": out}


def _up(m: int, c: Constants) -> np.ndarray:
    """Body components of up at accelerometer position m (nominal for 7-12)."""
    return t_br(m, c)[:, 0] if m > 12 else FIRST_COLUMN[m]


def _string_sum_geometry(data: CalibrationData, rows: list[ResultRow], noise: NoiseSpec,
                         keys: list[Key]) -> np.ndarray:
    """Covariance (pulses/s)^2 of the f2 - f1 data ``keys`` from what turns the input axis:
    pier tilt since the bubble reading and the settings' orientation errors (``covariance``).
    Zero where the model cannot be built (a partial day without the constants it needs)."""
    est = {(r.instrument, r.parameter): r.estimate for r in rows}
    try:
        return data_covariance_model(reduce(data), keys, data, noise, est).geometric()
    except (ValueError, KeyError, TypeError):
        return np.zeros((len(keys), len(keys)))


def check_string_sums(data: CalibrationData, rows: list[ResultRow],
                      noise: NoiseSpec | None = None, k_lim: float = K_RESULT) -> dict:
    """Each accelerometer's f1 + f2 over its positions against a + b u + c u^2; the residual
    of each position in units of its own sigma; beyond ``k_lim`` an Implausible naming the
    two counters.

    The sums' covariance: the white noise on f2 - f1 (NoiseSpec: one acceleration noise,
    which moves the strings push-pull, so the sum sees it only where the two gates differ),
    the clock count's quantization, the common drift, the master oscillator's aging
    (NoiseSpec.oscillator_drift_per_day; without it, an oscillator aging 1e-8 a day stopped
    the default lab's day here, and one at 1e-6 broke the fit by 530 sigma, though the
    constants moved by 0.01 and 0.44 sigma), and the input axis' turn by pier tilt and
    table setting (Chart I-4 geometry: the same du that moves f2 - f1 by
    D1 du moves the common mode 2 kappa u^2 of Chart IV-1 by 2 (2 kappa) u du, i.e. the
    fit's slope b + 2 c u times du; correlated across positions as the f2 - f1 data are).
    With pier factor 2.9 and accelerometer noise 0.3x (random lab 183) that term is 13-17
    sigma of the noise alone at the bisector positions 13, 14 (u = 0.7)."""
    noise = noise or NoiseSpec.model_validate({})
    c = data.constants
    est = {(r.instrument, r.parameter): r.estimate for r in rows}
    q = (noise.accel_white_micro_g_rt_hz * 1e-6) ** 2
    out: dict[str, float] = {}
    worst: tuple[float, int, int, float, float] | None = None  # |z|, k, m, r, sigma
    for k in (1, 2, 3):
        ab = [est.get((f"accel{k}", f"A.B{j}")) for j in (1, 2, 3)]
        a_vec = np.array(ab, dtype=float) if None not in ab else np.eye(3)[k - 1]
        d1 = float(est.get((f"accel{k}", "D1")) or 2000.0)
        d2 = float(est.get((f"accel{k}", "D2")) or 0.0)
        d3 = float(est.get((f"accel{k}", "D3")) or 0.0)
        ms, u, sums, var, mid = [], [], [], [], []
        for m, p in sorted(data.accel.items()):
            if (k, 1) not in p.gamma or (k, 2) not in p.gamma:
                continue
            f = [p.gamma[(k, ell)] / (p.n1[(k, ell)] * c.s1_t) for ell in (1, 2)]
            gates = [p.n1[(k, ell)] * c.s1_t for ell in (1, 2)]
            ms.append(m)
            mid.append(0.5 * (p.t0 + p.t1))
            u.append(c.g * float(a_vec @ _up(m, c)))
            sums.append(f[0] + f[1])
            # one acceleration noise moves the strings push-pull, each seen over its own
            # gate from t0: in the sum only the gates' difference, (D1/2)^2 q |1/T1 - 1/T2|
            var.append((0.5 * d1) ** 2 * q * abs(1.0 / gates[0] - 1.0 / gates[1])
                       + sum(noise.clock_quantization_var * (fi / (t / c.s1_t)) ** 2
                             for fi, t in zip(f, gates, strict=True))
                       + 2.0 * noise.string_common_drift_hz**2)
        if len(ms) < 4:
            continue  # three coefficients: nothing left to judge
        ua, y = np.array(u), np.array(sums)
        x = np.column_stack([np.ones(len(u)), ua, np.square(ua)])
        # the master oscillator's aging: each sum, counted against it, off by its own size
        # times the drift since the mean time; one rate for the day, so a rank-one term
        aging = y * (np.array(mid) - np.mean(mid)) / DAY * noise.oscillator_drift_per_day
        v0 = np.diag(var) + np.outer(aging, aging)
        geo = _string_sum_geometry(data, rows, noise, [("F", k, m) for m in ms])
        # d(f2 - f1)/du of Chart IV-1 at each position: the geometric part is D1' du
        diff_slope = d1 * (1.0 + 2.0 * d2 * ua + 3.0 * d3 * ua**2)
        cov = v0
        for _ in range(3):  # the slope of the sums comes from the fit: iterate
            beta, _ = _gls(x, y, cov)
            ratio = (beta[1] + 2.0 * beta[2] * ua) / diff_slope
            cov = v0 + np.outer(ratio, ratio) * geo
        beta, h = _gls(x, y, cov)
        resid = y - x @ beta
        cov_r = np.diag(cov) - np.einsum("ij,jk,ik->i", x, h, x)
        zs = []
        for m, r, v, vm in zip(ms, resid, cov_r, np.diag(cov), strict=True):
            if v <= (REDUNDANT**2) * vm:
                continue
            z = float(r / math.sqrt(v))
            out[f"accel{k} position {m}"] = z
            zs.append(abs(z))
        if zs and max(zs) > k_lim and (worst is None or max(zs) > worst[0]):
            worst = (max(zs), k, *_culprit(x, y, cov, ms))
    if worst is not None:
        _, k, m, r, s = worst
        raise Implausible(
            f"counter{2 * k - 1} and counter{2 * k} (accelerometer {k}'s strings)",
            f"Chart {_chart('F', m)} position {m}: the strings' common frequency "
            f"f1 + f2 is {r:+.4g} Hz off the other positions' ({r / s:+.1f} sigma, sigma "
            f"{s:.3g} Hz, limit {k_lim:g}): a wrong count")
    return out


def _gls(x: np.ndarray, y: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Generalized least squares: the coefficients and their covariance."""
    w = np.linalg.inv(cov)
    h = np.linalg.inv(x.T @ w @ x)
    return h @ (x.T @ (w @ y)), h


def _culprit(x: np.ndarray, y: np.ndarray, cov: np.ndarray, ms: list[int]
             ) -> tuple[int, float, float]:
    """The position whose removal leaves the others most consistent (least chi-square):
    where the garbled count is, even where the fit goes through it (the vertical pairs,
    whose sums are the sharpest); its sum against the others' fit and that residual's
    sigma (Hz)."""
    best: tuple[float, int, float, float] | None = None
    for i, m in enumerate(ms):
        keep = [j for j in range(len(ms)) if j != i]
        if len(keep) < x.shape[1]:
            break
        c = cov[np.ix_(keep, keep)]
        beta, h = _gls(x[keep], y[keep], c)
        e = y[keep] - x[keep] @ beta
        chi2 = float(e @ np.linalg.solve(c, e))
        r = float(y[i] - x[i] @ beta)
        s = math.sqrt(float(cov[i, i] + x[i] @ h @ x[i]))
        if best is None or chi2 < best[0]:
            best = (chi2, m, r, s)
    assert best is not None
    return best[1], best[2], best[3]
