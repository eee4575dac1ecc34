"""Chart II-15 step 8: compute the constants, their predicted standard errors, and the rows of
the Calibration Results Sheet (Chart II-5).

Predicted standard error: every estimate is a function of the reduced counter data z and,
through them, of the true orientation at each setting. With J the numerical Jacobian of the
estimator (central differences, one standard error per step) and Sigma_z the data
covariance of ``covariance.DataCovariance`` (noise, pier tilt, orientation errors carried
by the forward model), sigma = sqrt(diag(J Sigma_z J^T)), plus for the gyros the variance
of the turn of O and S about G that no position measures (``neglected``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from procedures.isu.calibration import chart_ii16
from procedures.isu.calibration.accel_equations import ACCEL_PARAMS, accel_estimates
from procedures.isu.calibration.covariance import DataCovariance, setting_of
from procedures.isu.calibration.forward import AccelModel, GyroModel
from procedures.isu.calibration.geometry import (
    FIRST_COLUMN,
    TableErrorModel,
    extended_geometry,
    extra_t_br,
    t_br,
)
from procedures.isu.calibration.gyro_equations import GYRO_PARAMS, gyro_estimates
from procedures.isu.calibration.inputs import CalibrationData, Constants
from procedures.isu.calibration.neglected import corrected_gyro_estimates
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.calibration.reduce import Key, Reduced, reduce
from procedures.isu.calibration.vectors import cross3, norm3
from procedures.isu.sheets import ConstantsCorrelation, ResultRow

Row = tuple[str, str]  # (instrument, parameter)


def _central_difference(plus: float | None, minus: float | None, h: float, row: Row,
                        datum: Key) -> float:
    """d(constant)/d(datum) from the estimates with the datum moved by +h and -h."""
    if plus is None or minus is None:
        raise ValueError(f"{row[0]} {row[1]}: no estimate once datum {datum} moved by {h:g}")
    return (plus - minus) / (2 * h)


INSTRUMENTS = ("gyro1", "gyro2", "gyro3", "accel1", "accel2", "accel3")


def estimate_of(z: Mapping[Key, float], c: Constants, inst: str,
                corrected: bool = True) -> dict[Row, float | None]:
    """One instrument's Chart II-5 constants (``estimate``'s, for that instrument only);
    ``corrected`` False: the gyros' printed forms alone, without the neglected terms put
    back (``neglected``: they vanish with the drift coefficients)."""
    k = int(inst[-1])
    if inst.startswith("gyro"):
        forms = corrected_gyro_estimates if corrected else gyro_estimates
        return {(inst, p): v for p, v in forms(z, c, k).items()}
    return {(inst, p): v for p, v in accel_estimates(z, c.g, k).items()}


def estimate(z: Mapping[Key, float], c: Constants) -> dict[Row, float | None]:
    """All Chart II-5 constants from reduced data (None where not determined); the gyros'
    printed forms with the terms they neglect put back (``neglected``)."""
    out: dict[Row, float | None] = {}
    for inst in INSTRUMENTS:
        out.update(estimate_of(z, c, inst))
    return out


def closed_forms(data: CalibrationData) -> dict[Row, float | None]:
    """The closed forms' estimates of the day's data (``estimate`` of its reduced data):
    the ``constants_covariance`` estimates, without the covariance."""
    return estimate(reduce(data).values, data.constants)


def readers(key: Key) -> tuple[str, ...]:
    """The instruments whose closed forms read datum ``key`` (reduce's kinds): a gyro's
    rates and supplied misalignments its own, an accelerometer's differences and supplied
    (D1 D3) its own, the table rate every gyro's; an unknown kind, every instrument."""
    kind, k, _ = key
    if kind in ("G", "P"):
        return (f"gyro{k}",)
    if kind in ("F", "X"):
        return (f"accel{k}",)
    if kind == "w":
        return INSTRUMENTS[:3]
    return INSTRUMENTS


def _nominal_t_br(m: int, c: Constants) -> np.ndarray:
    """T^BRm from the survey, or (column missing) any frame with the nominal first column."""
    try:
        return t_br(m, c)
    except ValueError:
        c1 = FIRST_COLUMN[m]
        c2 = cross3(c1, [0.0, 0.0, 1.0] if abs(c1[2]) < 0.9 else [1.0, 0.0, 0.0])
        c2 = c2 / norm3(c2)
        return np.column_stack((c1, c2, cross3(c1, c2)))


def data_covariance(
    red: Reduced,
    keys: list[Key],
    data: CalibrationData,
    noise: NoiseSpec,
    est: Mapping[Row, float | None],
) -> np.ndarray:
    """The covariance of the reduced data ``keys`` (``covariance.DataCovariance.matrix``)."""
    return data_covariance_model(red, keys, data, noise, est).matrix()


def data_covariance_model(
    red: Reduced,
    keys: list[Key],
    data: CalibrationData,
    noise: NoiseSpec,
    est: Mapping[Row, float | None],
) -> DataCovariance:
    """The data covariance's builder at the estimates ``est`` (its pieces, e.g. the
    geometric part the string-sum check needs)."""
    c = data.constants

    def sub(prefix: str) -> dict[str, float | None]:
        return {p: v for (inst, p), v in est.items() if inst == prefix}

    gyros = {k: GyroModel.from_estimates(k, sub(f"gyro{k}")) for k in (1, 2, 3)}
    accels = {k: AccelModel.from_estimates(k, sub(f"accel{k}")) for k in (1, 2, 3)}
    settings = {s for key in keys if (s := setting_of(key)) is not None}
    extra = extra_t_br(data)  # positions beyond the manual (all-positions fit only)
    tbr = {s: extra[s[1]] if s[1] in extra else _nominal_t_br(s[1], c) for s in settings}
    table = TableErrorModel(extended_geometry(data), noise)
    return DataCovariance(red, keys, c, noise, gyros, accels, table, tbr)


Moved = dict[tuple[int, int], dict[Row, float | None]]  # (datum, +1 or -1): estimates


def estimator_jacobian(z: Mapping[Key, float], c: Constants, keys: list[Key], rows: list[Row],
                       steps: np.ndarray, corrected: bool = True,
                       keep: Moved | None = None) -> np.ndarray:
    """d(rows)/d(data) of the closed forms by central differences of ``steps``. Only the
    instruments that read a datum are estimated again: the others' rows would come out
    identical, their differences exactly zero. ``corrected``: as ``estimate_of``.
    ``keep``: filled with the readers' estimates at each datum moved by +h and -h (the
    residual check moves the same data by the same steps: ``Propagation``)."""
    jac = np.zeros((len(rows), len(keys)))
    index = {r: n for n, r in enumerate(rows)}
    for i, h in enumerate(steps):
        zp, zm = dict(z), dict(z)
        zp[keys[i]] = z[keys[i]] + h
        zm[keys[i]] = z[keys[i]] - h
        for inst in readers(keys[i]):
            ep, em = estimate_of(zp, c, inst, corrected), estimate_of(zm, c, inst, corrected)
            if keep is not None:
                keep.setdefault((i, 1), {}).update(ep)
                keep.setdefault((i, -1), {}).update(em)
            for r in ep:
                if r in index:
                    jac[index[r], i] = _central_difference(ep[r], em[r], h, r, keys[i])
    return jac


@dataclass(frozen=True)
class Propagation:
    """What ``constants_covariance`` computes on its way to J Sigma_z J^T and the residual
    check (calibration.checks) needs again, the same bits (issue 17: the check moved each
    datum by the same step and estimated its readers again, 0.05 s of a day): the reduced
    data's keys, their covariance Sigma_z, the steps (one standard error each), the
    estimates at the data as they are and at each datum moved by +h and -h. Read only."""

    keys: list[Key]
    data_cov: np.ndarray
    steps: np.ndarray
    est: dict[Row, float | None]
    moved: Moved


# the last few constants_covariance results by the content of their inputs: a day asks for
# the same one three times (the sheet, the all-positions side, the calibration file) and
# its residual check once (``propagation``)
_HELD: dict[str, tuple[list[Row], np.ndarray, Propagation]] = {}
HELD_RESULTS = 4


def _held(data: CalibrationData, noise: NoiseSpec | None
          ) -> tuple[list[Row], np.ndarray, Propagation]:
    """The held result of ``data`` and ``noise`` (computed now if it is not held). A
    result is held by its inputs' content (JSON: every float to the bit)."""
    noise = noise or NoiseSpec()
    key = data.model_dump_json() + noise.model_dump_json()
    if key not in _HELD:
        if len(_HELD) >= HELD_RESULTS:
            del _HELD[next(iter(_HELD))]
        _HELD[key] = _constants_covariance(data, noise)
    return _HELD[key]


def constants_covariance(
    data: CalibrationData, noise: NoiseSpec | None = None
) -> tuple[dict[Row, float | None], list[Row], np.ndarray]:
    """(estimates, the rows determined, their full covariance J Sigma_z J^T): J is the
    estimator's numerical Jacobian, Sigma_z the counter data's covariance. Handed out as
    a copy of the held result (``_held``)."""
    rows, cov, prop = _held(data, noise)
    return dict(prop.est), list(rows), cov.copy()


def propagation(data: CalibrationData, noise: NoiseSpec | None = None) -> Propagation:
    """The intermediate results of ``constants_covariance(data, noise)`` (``Propagation``;
    the held ones themselves: not to be changed)."""
    return _held(data, noise)[2]


def _constants_covariance(data: CalibrationData, noise: NoiseSpec
                          ) -> tuple[list[Row], np.ndarray, Propagation]:
    c = data.constants
    red = reduce(data)
    est = estimate(red.values, c)
    keys = list(red.values)
    cov = data_covariance(red, keys, data, noise, est)
    z0 = np.array([red.values[k] for k in keys])
    steps = np.sqrt(np.maximum(np.diag(cov), 0.0))
    steps = np.where(steps > 0, steps, 1e-9 * np.maximum(np.abs(z0), 1.0))
    rows = [r for r, v in est.items() if v is not None]
    moved: Moved = {}
    jac = estimator_jacobian(red.values, c, keys, rows, steps, keep=moved)
    m = jac @ cov @ jac.T
    return rows, 0.5 * (m + m.T), Propagation(keys, cov, steps, est, moved)


def _sigmas(est: dict[Row, float | None], rows: list[Row], cov: np.ndarray
            ) -> dict[Row, float | None]:
    sig: dict[Row, float | None] = {r: None for r in est}
    for r, v in zip(rows, np.diag(cov), strict=True):
        sig[r] = float(np.sqrt(max(v, 0.0)))
    return sig


def predicted_sigmas(
    data: CalibrationData, noise: NoiseSpec | None = None
) -> tuple[dict[Row, float | None], dict[Row, float | None]]:
    """(estimates, predicted standard errors) of every Chart II-5 constant."""
    est, rows, cov = constants_covariance(data, noise)
    return est, _sigmas(est, rows, cov)


def correlation(rows: list[Row], cov: np.ndarray) -> ConstantsCorrelation:
    """The constants' correlation matrix (four decimals) for the Calibration Results Sheet."""
    d = np.sqrt(np.maximum(np.diag(cov), 0.0))
    scale = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 0.0)
    r = np.clip(cov * np.outer(scale, scale), -1.0, 1.0)
    np.fill_diagonal(r, 1.0)
    return ConstantsCorrelation(rows=[f"{i} {p}" for i, p in rows],
                                matrix=[[round(float(x), 4) for x in line] for line in r])


def calibrate(data: CalibrationData, noise: NoiseSpec | None = None) -> list[ResultRow]:
    """Calibration Results Sheet rows (Chart II-5), one per instrument and parameter."""
    return calibrate_with_correlation(data, noise)[0]


def calibrate_with_correlation(data: CalibrationData, noise: NoiseSpec | None = None
                               ) -> tuple[list[ResultRow], ConstantsCorrelation]:
    """Chart II-5 rows and the correlation of the constants they determine."""
    est, det, cov = constants_covariance(data, noise)
    sig = _sigmas(est, det, cov)
    rows: list[ResultRow] = []
    for k in (1, 2, 3):
        for p in GYRO_PARAMS:
            v = est[(f"gyro{k}", p)]
            text = chart_ii16.GYRO[p][k - 1]
            if text == chart_ii16.SPECIAL:
                note = "separate experiment (Chart II-16): not computed here"
            elif v is None:
                note = "not determined by the given positions (Chart II-16)"
            else:
                note = ""
            rows.append(
                ResultRow(
                    instrument=f"gyro{k}",
                    parameter=p,
                    units=chart_ii16.GYRO_UNITS[p],
                    estimate=v,
                    sigma=sig[(f"gyro{k}", p)],
                    positions=text,
                    note=note,
                )
            )
    for k in (1, 2, 3):
        step7 = k in data.last_d1d3
        for p in ACCEL_PARAMS:
            v = est[(f"accel{k}", p)]
            note = "" if v is not None else "not determined by the given positions (Chart II-16)"
            d3_measured = est[(f"accel{k}", "D3")] is not None
            if v is not None and step7 and not d3_measured and p != "D3":
                note = "uses the supplied last (D1 D3) (Chart II-15 step 7)"
            if p == "D3" and v is None and step7:
                note = (
                    f"not measured; last (D1 D3) = {data.last_d1d3[k]:.6g} (pulses/s)/g^3 "
                    "supplied (Chart II-15 step 7)"
                )
            rows.append(
                ResultRow(
                    instrument=f"accel{k}",
                    parameter=p,
                    units=chart_ii16.ACCEL_UNITS[p],
                    estimate=v,
                    sigma=sig[(f"accel{k}", p)],
                    positions=chart_ii16.ACCEL[p][k - 1],
                    note=note,
                )
            )
    return rows, correlation(det, cov)


def without(corr: ConstantsCorrelation, names: list[str]) -> ConstantsCorrelation:
    """The correlation less the rows ``names`` (carried forward from an earlier sheet: their
    estimates are not this day's, so they are independent of it)."""
    keep = [i for i, r in enumerate(corr.rows) if r not in set(names)]
    return ConstantsCorrelation(rows=[corr.rows[i] for i in keep],
                                matrix=[[corr.matrix[i][j] for j in keep] for i in keep])
