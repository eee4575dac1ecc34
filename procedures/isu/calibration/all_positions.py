"""The all-positions estimator: one weighted least-squares fit of the Chart II-5 constants to
every reduced datum of the day, beside the manual's closed forms (issue 19).

Model: the Chart IV-1/IV-2 forward model of ``forward`` (full misaligned axes in every term)
at the positions of Chart I-4's geometry (``geometry.t_br``); the data are ``reduce_all``'s
rates of positions 1-15, any extra accelerometer positions (16 on, beyond the manual:
``[calibration] extra_accel_tilts_deg``) and any supplied (D1 D3) or [(G.B)/DeltaPhi]. The
table rate of positions 1-6 enters the model as measured; its error, correlated with the
gyro rates through counter 1's clock count, is carried into the residuals' covariance.
Weights: the full data covariance of ``covariance.DataCovariance`` (noise, drift, pier tilt,
the table's orientation errors as correlated noise). Gauss-Newton iterated (the model is
nonlinear in DeltaPhi, the axes and D1); the estimate's covariance is (J^T Sigma^-1 J)^-1
carried to the sheet's rows.

Parameters (internal): per gyro g = G/DeltaPhi (pulses/deg, three components) and the drift
coefficients in deg/hr; per accelerometer P = D1 A ((pulses/s)/g) and D1 D0, D1 D2, D1 D3.
A constant enters the fit only where the closed forms determine it too (Chart II-16): the
day's design leaves the others unidentifiable. Q_II and Q_IS enter as fitted constants when
a gyro has all of positions 1-15: the turns' mean rates carry Q_II (w.G)^2 at the table rate
(deg/hr at the default Q_II and the turns' rate), which the closed forms cancel in pair
differences; without all positions a turning pair enters only as its difference, as there.
The day's II-7 speed series (positions 1, 3, 5 at several speeds) enter too when given, with
their own covariance (``speed_covariance``): they sharpen each gyro's scale factor. Not
fitted: the Q_IS series (II-7Q) and the J experiment (II-10), which stay the sheet's.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from procedures.isu.calibration.compute import (
    Row,
    constants_covariance,
    correlation,
    data_covariance,
    estimate,
)
from procedures.isu.calibration.covariance import gyro_quantization_var
from procedures.isu.calibration.forward import NOMINAL_AXES, AccelModel, GyroModel, lab_axes
from procedures.isu.calibration.geometry import FIRST_COLUMN, extra_t_br, t_br
from procedures.isu.calibration.inputs import CalibrationData, Constants
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.calibration.reduce import Key, Record, Reduced, reduce_all
from procedures.isu.calibration.vectors import norm3
from procedures.isu.sheets import ConstantsCorrelation, ResultRow

GYRO_COEFS = ("R", "B_I", "B_O", "B_S", "C_II", "C_SS", "C_IS", "C_OS", "C_IO")
Q_TERMS = ("Q_II", "Q_IS")
ACCEL_INTERNAL = ("P1", "P2", "P3", "b0", "b2", "b3")
Param = tuple[str, str]  # (instrument, internal name)
LINEAR = frozenset((*GYRO_COEFS, *Q_TERMS, "b0", "b2", "b3"))  # the model is linear in these
MAX_ITERATIONS = 8


@dataclass
class Fit:
    """The all-positions estimate: Chart II-5 rows, their full covariance, and the fit."""

    estimates: dict[Row, float]
    rows: list[Row]  # order of ``covariance``
    covariance: np.ndarray
    chi2: float  # weighted residual sum of squares at the estimate
    dof: int
    iterations: int
    params: list[Param]
    theta: np.ndarray

    def sigma(self, row: Row) -> float:
        i = self.rows.index(row)
        return float(np.sqrt(max(self.covariance[i, i], 0.0)))


# ------------------------------------------------------------------------------ II-7 data
@dataclass(frozen=True)
class SpeedPoint:
    """One speed of a Chart II-7 series: gyro k along +B_k (position m = 2k - 1), the table
    turning at ``w_t_deg_s`` (signed, measured), output ``p_dot`` pulses/s over the gate."""

    k: int
    w_t_deg_s: float
    p_dot: float
    gate_s: float
    n1: float  # counter 1's clock ticks over the gate (Chart II-7 step 10)

    @property
    def position(self) -> int:
        return 2 * self.k - 1


def speed_points(series: Mapping[int, list[dict]], c: Constants) -> list[SpeedPoint]:
    """The II-7 speed series of the day (``DayData.nonlinearity``) as fit data."""
    out = []
    for k, pts in sorted(series.items()):
        for p in pts:
            w_t = (p["w_deg_hr"] + c.w_sin_lambda) / 3600.0  # the table's rate, deg/s
            out.append(SpeedPoint(int(k), w_t, p["p_dot"], abs(p["counts"] / p["p_dot"]),
                                  float(p["ticks"])))
    return out


def speed_covariance(points: list[SpeedPoint], noise: NoiseSpec,
                     dphi_deg: Mapping[int, float]) -> np.ndarray:
    """Covariance of the speed series' rates, pulses/s: quantization at the count's two
    edges, read at the rebalance loop's sampling instants (``gyro_quantization_var``, as
    positions 1-6's turns: at 15 deg/s a sample holds about one pulse), and angle random walk
    per gate, the pier's tilt change about the rotary axis (south) over the gate, and the
    gyro's random drift, taken as one offset common to a gyro's series (correlation time an
    hour, the series well within it)."""
    n = len(points)
    out = np.zeros((n, n))
    _, nn0, _ = noise.tilt_covariance(0.0)
    for i, p in enumerate(points):
        to_pulses = 1.0 / (3600.0 * dphi_deg[p.k])  # deg/hr -> pulses/s
        t = p.gate_s
        arw = noise.gyro_arw_deg_rt_hr**2 * (t / 3600.0) / (dphi_deg[p.k] * t) ** 2
        _, nn1, _ = noise.tilt_covariance(t)
        tilt = 2.0 * float(nn0 - nn1) * (180.0 / np.pi / dphi_deg[p.k] / t) ** 2
        gate = Record(("G", p.k, p.position), length=t, n1=p.n1)
        out[i, i] += gyro_quantization_var(p.p_dot, gate, noise) + arw + tilt
        for j, q in enumerate(points):
            if q.k == p.k:
                out[i, j] += (noise.gyro_drift_sigma_deg_hr * to_pulses) ** 2
    return out


# ------------------------------------------------------------------------------ parameters
def _gyro_model(k: int, p: Mapping[str, float]) -> GyroModel:
    g = np.array([p["g1"], p["g2"], p["g3"]])
    G, O, S = lab_axes(k, g)  # noqa: E741 - the report's symbols
    coef = {t: float(p.get(t, 0.0)) for t in (*GYRO_COEFS, *Q_TERMS)}
    return GyroModel(1.0 / float(norm3(g)), G, O, S, coef)


def _accel_model(p: Mapping[str, float]) -> AccelModel:
    P = np.array([p["P1"], p["P2"], p["P3"]])
    d1 = float(norm3(P))
    return AccelModel(d1, P / d1, p["b0"] / d1, p["b2"] / d1, p["b3"] / d1)


def internal_from_rows(values: Mapping[Row, float | None], inst: str) -> dict[str, float]:
    """Internal parameters of one instrument from Chart II-5 values (None read as 0)."""

    def v(name: str, default: float = 0.0) -> float:
        x = values.get((inst, name))
        return default if x is None else float(x)

    if inst.startswith("gyro"):
        dphi = v("DeltaPhi", 3.0 / 3600.0)
        k = int(inst[4:])
        nominal = NOMINAL_AXES[k - 1][0]
        out = {f"g{j}": v(f"G.B{j}", float(nominal[j - 1])) / dphi for j in (1, 2, 3)}
        out.update({t: v(t) for t in (*GYRO_COEFS, *Q_TERMS)})
        return out
    d1 = v("D1", 2000.0)
    k = int(inst[5:])
    out = {f"P{j}": d1 * v(f"A.B{j}", 1.0 if j == k else 0.0) for j in (1, 2, 3)}
    out.update({"b0": d1 * v("D0"), "b2": d1 * v("D2"), "b3": d1 * v("D3")})
    return out


def rows_from_internal(p: Mapping[str, float], inst: str) -> dict[str, float]:
    """Chart II-5 values of one instrument from its internal parameters."""
    if inst.startswith("gyro"):
        g = np.array([p["g1"], p["g2"], p["g3"]])
        norm = float(norm3(g))
        out = {"DeltaPhi": 1.0 / norm}
        out.update({f"G.B{j}": float(g[j - 1]) / norm for j in (1, 2, 3)})
        out.update({t: float(p[t]) for t in (*GYRO_COEFS, *Q_TERMS) if t in p})
        return out
    P = np.array([p["P1"], p["P2"], p["P3"]])
    d1 = float(norm3(P))
    out = {"D1": d1}
    out.update({f"A.B{j}": float(P[j - 1]) / d1 for j in (1, 2, 3)})
    out.update({"D0": p["b0"] / d1, "D2": p["b2"] / d1, "D3": p["b3"] / d1})
    return out


class _Models:
    """Each instrument's forward model at one parameter set, built on first use: a model
    evaluation reads the same instrument's model for many data."""

    def __init__(self, p: Mapping[str, dict[str, float]]) -> None:
        self.p = p
        self.gyros: dict[int, GyroModel] = {}
        self.accels: dict[int, AccelModel] = {}

    def gyro(self, k: int) -> GyroModel:
        if k not in self.gyros:
            self.gyros[k] = _gyro_model(k, self.p[f"gyro{k}"])
        return self.gyros[k]

    def accel(self, k: int) -> AccelModel:
        if k not in self.accels:
            self.accels[k] = _accel_model(self.p[f"accel{k}"])
        return self.accels[k]


# ------------------------------------------------------------------------------ the design
@dataclass
class Design:
    """Which constants the day determines, the data combinations fitted and their model."""

    data: CalibrationData
    red: Reduced
    keys: list[Key]  # every reduced datum, the order of Sigma_z
    params: list[Param]  # free
    base: dict[str, dict[str, float]]  # every instrument's internal parameters (held ones)
    combos: list[dict[Key, float]]  # each fitted datum as a combination of reduced data
    rows: list[Row]  # Chart II-5 rows the fit determines
    speeds: list[SpeedPoint]  # II-7 data fitted after the combinations
    extra: dict[int, np.ndarray] = field(default_factory=dict)  # T^BR of positions 16 on
    t_br_cache: dict[int, np.ndarray] = field(default_factory=dict, repr=False, compare=False)

    def instruments(self) -> list[str]:
        return sorted(self.base)

    def theta0(self) -> np.ndarray:
        return np.array([self.base[i][n] for i, n in self.params])

    def values(self, theta: np.ndarray) -> dict[str, dict[str, float]]:
        out = {i: dict(p) for i, p in self.base.items()}
        for (i, n), x in zip(self.params, theta, strict=True):
            out[i][n] = float(x)
        return out

    def datum(self, key: Key, p: Mapping[str, dict[str, float]], w: float | None,
              models: _Models | None = None) -> float:
        """Forward model of one reduced datum (``w``: the measured table rate, 1-6)."""
        models = models if models is not None else _Models(p)
        return cast(float, self._at(key, models, w, terms=False))

    def terms(self, key: Key, models: _Models, w: float | None) -> dict[str, float]:
        """d(datum)/d(each internal parameter it is linear in): a gyro's drift coefficients,
        an accelerometer's D1 D0, D1 D2, D1 D3, a supplied G/DeltaPhi component."""
        return cast(dict[str, float], self._at(key, models, w, terms=True))

    def _at(self, key: Key, models: _Models, w: float | None, terms: bool
            ) -> float | dict[str, float]:
        """A datum's model value, or (``terms``) its exact linear derivatives."""
        kind, k, m = key
        c = self.data.constants
        if kind == "G":
            gm = models.gyro(k)
            if m <= 6:
                turning = gm.turning_terms if terms else gm.turning_rate
                return turning(FIRST_COLUMN[m], float(w or 0.0), c)
            t = self._t_br(m)
            static = gm.static_terms if terms else gm.static_rate
            return static(t[:, 0], t[:, 1], c)
        if kind == "F":
            am = models.accel(k)
            return (am.difference_terms if terms else am.difference)(self._t_br(m)[:, 0], c)
        if kind == "X":
            return {"b3": 1.0} if terms else models.p[f"accel{k}"]["b3"]
        if kind == "P":
            return {f"g{m}": 1.0} if terms else models.p[f"gyro{k}"][f"g{m}"]
        raise ValueError(f"no model for datum {key}")

    def _t_br(self, m: int) -> np.ndarray:
        """T^BRm of the day's survey, computed once per design (the constants are fixed)."""
        if m not in self.t_br_cache:
            self.t_br_cache[m] = self.extra[m] if m in self.extra else t_br(m, self.data.constants)
        return self.t_br_cache[m]

    def model(self, theta: np.ndarray, w: Mapping[int, float] | None = None,
              only: list[int] | None = None) -> np.ndarray:
        """The fitted combinations' model values (``only``: those indices)."""
        p = self.values(theta)
        tw = w if w is not None else {m: self.red.values[("w", 0, m)]
                                      for (kind, _, m) in self.keys if kind == "w"}
        n = len(self.combos)
        which = range(n + len(self.speeds)) if only is None else only
        c = self.data.constants
        models = _Models(p)
        out = []
        for i in which:
            if i >= n:
                sp = self.speeds[i - n]
                out.append(models.gyro(sp.k).turning_rate(FIRST_COLUMN[sp.position],
                                                          sp.w_t_deg_s, c))
                continue
            out.append(sum(a * self.datum(key, p, tw.get(key[2]), models)
                           for key, a in self.combos[i].items()))
        return np.array(out)

    def combos_of(self, inst: str) -> list[int]:
        """Indices of the combinations an instrument's parameters enter."""
        kinds = ("G", "P") if inst.startswith("gyro") else ("F", "X")
        k = int(inst[-1])
        n = len(self.combos)
        return [i for i, cb in enumerate(self.combos)
                if any(key[0] in kinds and key[1] == k for key in cb)] + [
            n + j for j, sp in enumerate(self.speeds) if inst == f"gyro{sp.k}"]

    def observed(self) -> np.ndarray:
        return np.array([sum(a * self.red.values[key] for key, a in cb.items())
                         for cb in self.combos] + [sp.p_dot for sp in self.speeds])

    def data_map(self, theta: np.ndarray) -> np.ndarray:
        """A: fitted residuals = A (reduced data), the measured table rates included."""
        index = {k: i for i, k in enumerate(self.keys)}
        a = np.zeros((len(self.combos), len(self.keys)))
        for r, cb in enumerate(self.combos):
            for key, x in cb.items():
                a[r, index[key]] += x
        rates = {m: self.red.values[("w", 0, m)] for (kind, _, m) in self.keys if kind == "w"}
        for m, w in rates.items():
            h = 1e-7 * max(abs(w), 1e-3)
            idx = [i for i, cb in enumerate(self.combos)
                   if any(key[0] == "G" and key[2] == m for key in cb)]
            if not idx:
                continue
            up = self.model(theta, {**rates, m: w + h}, idx)
            dn = self.model(theta, {**rates, m: w - h}, idx)
            a[idx, index[("w", 0, m)]] -= (up - dn) / (2 * h)
        return a

    def linear_columns(self, theta: np.ndarray) -> dict[int, np.ndarray]:
        """The Jacobian's columns of the parameters the model is linear in (``terms``),
        exact where central differences carry rounding: index -> column."""
        p = self.values(theta)
        models = _Models(p)
        tw = {m: self.red.values[("w", 0, m)] for (kind, _, m) in self.keys if kind == "w"}
        rows = len(self.combos) + len(self.speeds)
        cols: dict[int, np.ndarray] = {}
        index = {par: j for j, par in enumerate(self.params) if par[1] in LINEAR}
        n = len(self.combos)
        c = self.data.constants
        for i in range(rows):
            if i >= n:
                sp = self.speeds[i - n]
                parts = [(f"gyro{sp.k}", 1.0, models.gyro(sp.k).turning_terms(
                    FIRST_COLUMN[sp.position], sp.w_t_deg_s, c))]
            else:
                parts = [(f"{'gyro' if key[0] in ('G', 'P') else 'accel'}{key[1]}", a,
                          self.terms(key, models, tw.get(key[2])))
                         for key, a in self.combos[i].items()]
            for inst, a, d in parts:
                for name, x in d.items():
                    j = index.get((inst, name))
                    if j is not None:
                        cols.setdefault(j, np.zeros(rows))[i] += a * x
        return {j: cols.get(j, np.zeros(rows)) for j in index.values()}

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        out = np.zeros((len(self.combos) + len(self.speeds), len(theta)))
        rows = {inst: self.combos_of(inst) for inst in self.base}
        for j, col in self.linear_columns(theta).items():
            out[:, j] = col
        for j, (inst, n) in enumerate(self.params):
            if n in LINEAR:
                continue
            h = _step(n, theta[j])
            tp, tm = theta.copy(), theta.copy()
            tp[j] += h
            tm[j] -= h
            idx = rows[inst]
            out[idx, j] = (self.model(tp, only=idx) - self.model(tm, only=idx)) / (2 * h)
        return out

    def row_jacobian(self, theta: np.ndarray) -> np.ndarray:
        """d(Chart II-5 rows)/d(free internal parameters)."""

        def rows_of(t: np.ndarray) -> np.ndarray:
            p = self.values(t)
            vals = {i: rows_from_internal(p[i], i) for i in p}
            return np.array([vals[i][n] for i, n in self.rows])

        out = np.zeros((len(self.rows), len(theta)))
        for j, (_, n) in enumerate(self.params):
            h = _step(n, theta[j])
            tp, tm = theta.copy(), theta.copy()
            tp[j] += h
            tm[j] -= h
            out[:, j] = (rows_of(tp) - rows_of(tm)) / (2 * h)
        return out

    def row_values(self, theta: np.ndarray) -> dict[Row, float]:
        p = self.values(theta)
        vals = {i: rows_from_internal(p[i], i) for i in p}
        return {(i, n): vals[i][n] for i, n in self.rows}


def _step(name: str, x: float) -> float:
    """Central-difference step of an internal parameter (the model is smooth in each)."""
    floor = {"Q_II": 1e-11, "Q_IS": 1e-11}.get(name, 1e-4)
    return max(1e-6 * abs(x), floor)


def design(data: CalibrationData, closed: Mapping[Row, float | None] | None = None,
           red: Reduced | None = None, speeds: list[SpeedPoint] | None = None) -> Design:
    """The fit's design for the day's data: the closed forms' constants are the free ones;
    ``speeds`` (II-7) of a gyro the fit has Q_II for."""
    red = red or reduce_all(data)
    c: Constants = data.constants
    closed = closed if closed is not None else estimate(red.values, c)
    keys = list(red.values)
    params: list[Param] = []
    base: dict[str, dict[str, float]] = {}
    combos: list[dict[Key, float]] = []
    rows: list[Row] = []
    for k in (1, 2, 3):
        inst = f"gyro{k}"
        if closed.get((inst, "DeltaPhi")) is None:
            continue
        base[inst] = internal_from_rows(closed, inst)
        free = ["g1", "g2", "g3", *(t for t in GYRO_COEFS if closed.get((inst, t)) is not None)]
        full = all(("G", k, m) in red.values for m in range(1, 16))
        if full:
            free += list(Q_TERMS)
        params += [(inst, n) for n in free]
        rows += [(inst, n) for n in ("DeltaPhi", "G.B1", "G.B2", "G.B3")]
        rows += [(inst, t) for t in (*GYRO_COEFS, *Q_TERMS) if t in free]
        for m in range(1, 16):
            key = ("G", k, m)
            if key not in red.values:
                continue
            if m <= 6 and not full:  # pair difference only (the closed forms' use)
                if m % 2 == 1 and ("G", k, m + 1) in red.values:
                    combos.append({key: 1.0, ("G", k, m + 1): -1.0})
                continue
            combos.append({key: 1.0})
        combos += [{key: 1.0} for key in keys if key[0] == "P" and key[1] == k]
    for k in (1, 2, 3):
        inst = f"accel{k}"
        if closed.get((inst, "D1")) is None:
            continue
        base[inst] = internal_from_rows(closed, inst)
        if ("X", k, 0) in red.values and closed.get((inst, "D3")) is None:
            base[inst]["b3"] = red.values[("X", k, 0)]
        names = {"b0": "D0", "b2": "D2"}
        free = ["P1", "P2", "P3"]
        free += [n for n, r in names.items() if closed.get((inst, r)) is not None]
        free += ["b3"] if (closed.get((inst, "D3")) is not None
                           or ("X", k, 0) in red.values) else []
        params += [(inst, n) for n in free]
        rows += [(inst, n) for n in ("D1", "A.B1", "A.B2", "A.B3")]
        rows += [(inst, r) for n, r in (*names.items(), ("b3", "D3")) if n in free]
        combos += [{key: 1.0} for key in keys if key[0] in ("F", "X") and key[1] == k]
    with_q = {i for i, n in params if n == "Q_II"}
    kept = [sp for sp in (speeds or []) if f"gyro{sp.k}" in with_q]
    return Design(data, red, keys, params, base, combos, rows, kept, extra_t_br(data))


# ------------------------------------------------------------------------------ the fit
def _weights(a: np.ndarray, cov_z: np.ndarray, cov_s: np.ndarray | None = None) -> np.ndarray:
    """Inverse of the fitted residuals' covariance: A Sigma_z A^T, and the II-7 speeds'."""
    s = a @ cov_z @ a.T
    if cov_s is not None and cov_s.size:
        n = s.shape[0]
        s = np.block([[s, np.zeros((n, cov_s.shape[0]))], [np.zeros((cov_s.shape[0], n)), cov_s]])
    s = 0.5 * (s + s.T)
    floor = 1e-18 * max(float(np.max(np.diag(s))), 1e-300)
    s += np.diag(np.where(np.diag(s) > floor, 0.0, floor))
    return np.linalg.inv(s)


def _information(d: Design, theta: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    jac = d.jacobian(theta)
    return jac, jac.T @ w @ jac


def _speed_cov(d: Design, noise: NoiseSpec, closed: Mapping[Row, float | None]) -> np.ndarray:
    dphi = {sp.k: float(closed[(f"gyro{sp.k}", "DeltaPhi")] or 0.0) for sp in d.speeds}
    return speed_covariance(d.speeds, noise, dphi)


def fit(data: CalibrationData, noise: NoiseSpec | None = None,
        closed: Mapping[Row, float | None] | None = None,
        cov_z: np.ndarray | None = None,
        series: Mapping[int, list[dict]] | None = None) -> Fit:
    """The all-positions estimate of the day's constants and its full covariance;
    ``series``: the day's II-7 speed series (``DayData.nonlinearity``), fitted too."""
    noise = noise or NoiseSpec()
    red = reduce_all(data)
    closed = closed if closed is not None else estimate(red.values, data.constants)
    d = design(data, closed, red, speed_points(series or {}, data.constants))
    if not d.params:
        return Fit({}, [], np.zeros((0, 0)), 0.0, 0, 0, [], np.zeros(0))
    if cov_z is None:
        cov_z = data_covariance(red, d.keys, data, noise, closed)
    cov_s = _speed_cov(d, noise, closed)
    theta = d.theta0()
    z = d.observed()
    w = _weights(d.data_map(theta), cov_z, cov_s)
    iterations = 0
    while iterations < MAX_ITERATIONS:
        iterations += 1
        r = z - d.model(theta)
        jac, info = _information(d, theta, w)
        step = np.linalg.solve(info, jac.T @ w @ r)
        theta = theta + step
        scale = np.sqrt(np.maximum(np.diag(np.linalg.inv(info)), 1e-300))
        if np.all(np.abs(step) < 1e-6 * scale):
            break
    w = _weights(d.data_map(theta), cov_z, cov_s)
    jac, info = _information(d, theta, w)
    cov_theta = np.linalg.inv(info)
    rj = d.row_jacobian(theta)
    cov = rj @ cov_theta @ rj.T
    r = z - d.model(theta)
    return Fit(d.row_values(theta), list(d.rows), 0.5 * (cov + cov.T), float(r @ w @ r),
               len(z) - len(theta), iterations, list(d.params), theta)


def cramer_rao(data: CalibrationData, at: Mapping[Row, float | None],
               noise: NoiseSpec | None = None,
               closed: Mapping[Row, float | None] | None = None,
               cov_z: np.ndarray | None = None,
               series: Mapping[int, list[dict]] | None = None) -> tuple[list[Row], np.ndarray]:
    """The Cramer-Rao bound of the day's design on the fitted constants: the inverse Fisher
    information (Gaussian data of covariance Sigma_z) at the constants ``at`` (the truth in a
    simulation, the estimate in a laboratory), carried to the Chart II-5 rows."""
    noise = noise or NoiseSpec()
    red = reduce_all(data)
    closed = closed if closed is not None else estimate(red.values, data.constants)
    d = design(data, closed, red, speed_points(series or {}, data.constants))
    if cov_z is None:
        cov_z = data_covariance(red, d.keys, data, noise, closed)
    for inst in d.base:
        d.base[inst].update({n: x for n, x in internal_from_rows(at, inst).items()})
    theta = d.theta0()
    w = _weights(d.data_map(theta), cov_z, _speed_cov(d, noise, closed))
    _, info = _information(d, theta, w)
    rj = d.row_jacobian(theta)
    cov = rj @ np.linalg.inv(info) @ rj.T
    return list(d.rows), 0.5 * (cov + cov.T)

def sigma_ratios(sigmas: Mapping[Row, float | None], crb: tuple[list[Row], np.ndarray]
                 ) -> dict[Row, float]:
    """Each row's sigma over its Cramer-Rao bound (rows the bound covers)."""
    rows, cov = crb
    out = {}
    for i, r in enumerate(rows):
        s = sigmas.get(r)
        if s is not None and cov[i, i] > 0:
            out[r] = float(s) / float(np.sqrt(cov[i, i]))
    return out


# ------------------------------------------------------------------------------ the sheet
ESTIMATORS = ("closed-form", "all-positions")


def side_by_side(rows: list[ResultRow], data: CalibrationData, noise: NoiseSpec | None,
                 estimator: str = "closed-form",
                 series: Mapping[int, list[dict]] | None = None
                 ) -> tuple[list[Row], np.ndarray]:
    """Fill the Calibration Results Sheet's rows (in place) with both estimators and the
    Cramer-Rao bound at the all-positions estimate; the rows' estimate and sigma become
    ``estimator``'s. Returns that estimator's rows and full covariance (calibration file).
    ``series``: the II-7 speed series, which the fit takes too."""
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator: {estimator!r} is not one of {', '.join(ESTIMATORS)}")
    noise = noise or NoiseSpec()
    closed, cf_rows, cf_cov = constants_covariance(data, noise)
    side = all_positions_side(data, noise, closed, series)
    fill_columns(rows, side_columns(rows, side, estimator, cf_rows))
    f = side.fit
    if estimator == "all-positions" and f.rows:
        return f.rows, f.covariance
    return cf_rows, cf_cov


@dataclass
class Side:
    """The all-positions side of the Calibration Results Sheet: the fit, and the
    Cramer-Rao bound at its estimate on the rows ``bound_rows``."""

    fit: Fit
    bound_rows: list[Row]
    bound: np.ndarray


def all_positions_side(data: CalibrationData, noise: NoiseSpec | None,
                       closed: Mapping[Row, float | None],
                       series: Mapping[int, list[dict]] | None = None) -> Side:
    """The all-positions fit and its Cramer-Rao bound from the day's data and the closed
    forms' estimates ``closed`` (``compute.closed_forms``): a pure function of them, no
    sheet row needed, so the closed-form day sends it to its second process as soon as
    its data are prepared (Run.meanwhile, issue 17). A design the fit cannot invert gives
    an empty side (the closed forms stand)."""
    noise = noise or NoiseSpec()
    red = reduce_all(data)
    d = design(data, closed, red)
    cov_z = data_covariance(red, d.keys, data, noise, closed)
    try:
        f = fit(data, noise, closed, cov_z, series)
        bound_rows, bound = (cramer_rao(data, {**closed, **f.estimates}, noise, closed, cov_z,
                                        series) if f.rows else ([], np.zeros((0, 0))))
    except np.linalg.LinAlgError:
        f = Fit({}, [], np.zeros((0, 0)), 0.0, 0, 0, [], np.zeros(0))
        bound_rows, bound = [], np.zeros((0, 0))
    return Side(f, bound_rows, bound)


def side_columns(rows: list[ResultRow], side: Side, estimator: str = "closed-form",
                 determined: Collection[Row] = ()) -> list[dict[str, Any]]:
    """What each row of the sheet shows beside its closed form (field -> value): the
    all-positions estimate, its sigma and the Cramer-Rao sigma; under the all-positions
    estimator these become the estimate and sigma of the rows the closed forms
    ``determined`` too."""
    f, bound_rows, bound = side.fit, side.bound_rows, side.bound
    columns: list[dict[str, Any]] = []
    for r in rows:
        key = (r.instrument, r.parameter)
        col: dict[str, Any] = {"closed_form": r.estimate, "closed_form_sigma": r.sigma}
        if key in f.estimates:
            i = bound_rows.index(key)
            col |= {"all_positions": f.estimates[key], "all_positions_sigma": f.sigma(key),
                    "cramer_rao_sigma": float(np.sqrt(max(bound[i, i], 0.0)))}
            if estimator == "all-positions" and key in determined:
                col |= {"estimate": col["all_positions"], "sigma": col["all_positions_sigma"],
                        "estimator": estimator}
        columns.append(col)
    return columns


def fill_columns(rows: list[ResultRow], columns: list[dict[str, Any]]) -> None:
    """``side_columns``'s values written on the rows (in place)."""
    for r, col in zip(rows, columns, strict=True):
        for name, value in col.items():
            setattr(r, name, value)


def chosen_correlation(rows: list[ResultRow], chosen: tuple[list[Row], np.ndarray],
                       estimator: str) -> ConstantsCorrelation:
    """The correlation of the sheet rows whose estimate is ``estimator``'s (``chosen``:
    ``side_by_side``'s covariance): what the alignments combine the constants with (Chart
    II-15 step 8). Q_II, Q_IS stay the special experiments' and are left out."""
    order, cov = chosen
    mine = {(r.instrument, r.parameter) for r in rows if r.estimate is not None
            and r.estimator == estimator and r.parameter not in Q_TERMS}
    keep = [i for i, r in enumerate(order) if r in mine]
    return correlation([order[i] for i in keep], cov[np.ix_(keep, keep)])

