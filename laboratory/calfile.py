"""The calibration file (DIR/calibration.json): a day's constants in a documented, versioned
form that can leave the laboratory (docs/calibration-file.md, calibration-file.schema.json).

It holds the unit's identity (run.json ``unit``), its validity (date, run_uid), every Chart
II-5 constant with units and predicted sigma, their covariance (full where the calibration
computes it, else diagonal, and the file says which), the body frame the constants refer to
(report 000's B axes) and the IEU timer period that turns timer counts into seconds.
``load`` refuses a file that is not one, naming the field.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from laboratory.record import write_json
from procedures.isu.calibration.all_positions import Q_TERMS, fit
from procedures.isu.calibration.compute import constants_covariance
from procedures.isu.calibration.inputs import CalibrationData
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.computations import calibration_data
from procedures.isu.day import DayData
from procedures.isu.plan import DayPlan
from procedures.isu.sheets import CalibrationResults
from procedures.isu.site import Site
from station.config.isu import StationConfig
from station.errors import UseError

FORMAT = "station-calibration-file"
SCHEMA_VERSION = 2  # 2: covariance.estimator (issue 19); 1 is still read
READABLE_VERSIONS = (1, 2)
FILE_NAME = "calibration.json"
Row = tuple[str, str]  # (instrument, parameter)

GYRO_PARAMS = ("DeltaPhi", "G.B1", "G.B2", "G.B3", "R", "B_I", "B_O", "B_S", "C_II", "C_SS",
               "C_IS", "C_OS", "C_IO", "Q_II", "Q_IS", "J")
ACCEL_PARAMS = ("D1", "A.B1", "A.B2", "A.B3", "D0", "D2", "D3")
INSTRUMENTS = {**{f"gyro{k}": GYRO_PARAMS for k in (1, 2, 3)},
               **{f"accel{k}": ACCEL_PARAMS for k in (1, 2, 3)}}

# Report 000 (DOMAIN.md, Chart III-9): B1 is the normal of mirror 1, B2 lies in the plane of
# mirror 1's normal and mirror 2's, B3 = B1 x B2; the instruments' nominal axes in B.
BODY_FRAME = {
    "name": "B",
    "definition": "ISU body axes of report 000: B1 along the normal of mirror 1; B2 in the "
                  "plane of the normals of mirrors 1 and 2, perpendicular to B1; "
                  "B3 = B1 x B2 (right-handed)",
    "gyro_axes": {  # nominal input (G), output (O) and spin (S) axes; G = O x S
        "gyro1": {"G": "+B1", "O": "+B3", "S": "-B2"},
        "gyro2": {"G": "+B2", "O": "+B1", "S": "-B3"},
        "gyro3": {"G": "+B3", "O": "+B1", "S": "+B2"},
    },
    "accel_axes": {"accel1": {"A": "+B1"}, "accel2": {"A": "+B2"}, "accel3": {"A": "+B3"}},
    "note": "G.Bj and A.Bj are the calibrated input axes' direction cosines in B",
}
MODELS = {
    "accelerometer": "Chart IV-1: f2 - f1 = D1 (u + D0 + D2 u^2 + D3 u^3), u = a.A / g, "
                     "g = 9.80665 m/s^2",
    "gyro": "Chart IV-2: DeltaPhi (pulses/s) = w.G + R + B_I a.G + B_O a.O + B_S a.S "
            "+ C_II (a.G)^2 + C_SS (a.S)^2 + C_IS a.G a.S + C_OS a.O a.S + C_IO a.G a.O "
            "+ Q_II (w.G)^2 + Q_IS (w.G)(w.S) + J d(w.O)/dt; rates deg/hr, a in g",
}


class CalibrationFileError(UseError, ValueError):
    """A calibration file that is not one (the message names the file and the field)."""


# ----- covariance -----
def calibration_covariance(data: CalibrationData, noise: NoiseSpec,
                           estimator: str = "closed-form",
                           series: Mapping[int, list[dict]] | None = None
                           ) -> tuple[list[Row], np.ndarray]:
    """Full covariance of the constants the calibration program computes, of the sheet's
    estimator: J Sigma_z J^T of the closed forms (compute.predicted_sigmas keeps only its
    diagonal), or (J_f^T Sigma_z^-1 J_f)^-1 of the all-positions fit (with the II-7 speed
    ``series`` when the day ran them, as the sheet's)."""
    if estimator == "all-positions":  # Q_II, Q_IS on the sheet are the special experiments'
        f = fit(data, noise, series=series)
        keep = [i for i, r in enumerate(f.rows) if r[1] not in Q_TERMS]
        return [f.rows[i] for i in keep], f.covariance[np.ix_(keep, keep)]
    _, rows, cov = constants_covariance(data, noise)
    return rows, cov


# ----- writing -----
def calibration_document(out: Path, calib: CalibrationResults, timer_period_s: float,
                         covariance: tuple[list[Row], np.ndarray] | None = None,
                         covariance_note: str = "",
                         estimator: str = "closed-form") -> dict[str, Any]:
    """The calibration file of the run in ``out`` (its run.json gives identity and validity)."""
    run = json.loads((out / "run.json").read_text())
    constants = []
    for r in calib.rows:
        constants.append({"instrument": r.instrument, "parameter": r.parameter,
                          "units": r.units, "value": r.estimate, "sigma": r.sigma,
                          "note": r.note})
    order = [[r.instrument, r.parameter] for r in calib.rows
             if r.estimate is not None and r.sigma is not None]
    sig = {(r.instrument, r.parameter): float(r.sigma) for r in calib.rows
           if r.estimate is not None and r.sigma is not None}
    n = len(order)
    mat = np.diag([sig[(i, p)] ** 2 for i, p in order]) if n else np.zeros((0, 0))
    kind = "diagonal"
    full_rows: list[str] = []
    note = covariance_note or "the calibration's predicted sigmas only: correlations unknown"
    if covariance is not None and not any(r in set(covariance[0])
                                          for r in map(tuple, order)):
        covariance, note = None, "no constant of the calibration program determined"
    if covariance is not None:
        rows, cm = covariance
        idx = {tuple(x): i for i, x in enumerate(order)}
        pos = [(idx[r], a) for a, r in enumerate(rows) if r in idx]
        for i, a in pos:
            for j, b in pos:
                mat[i, j] = cm[a, b]
        kind = "full"
        full_rows = [f"{r[0]} {r[1]}" for r in rows if r in idx]
        diag_only = [f"{i} {p}" for i, p in order if (i, p) not in set(rows)]
        how = ("(J_f^T Sigma_z^-1 J_f)^-1 of the all-positions fit" if estimator ==
               "all-positions" else "J Sigma_z J^T of the calibration program")
        note = (f"{how} (Chart II-15 step 8); "
                + ("rows not computed by that program (separate experiments of Chart "
                   "II-16, or constants taken from another sheet) have their variance only: "
                   + ", ".join(diag_only) if diag_only else "every row correlated"))
    started = run.get("started_utc") or ""
    return {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "unit": run.get("unit", {}),
        "laboratory": run.get("laboratory"),
        "station_id": run.get("station_id"),
        "validity": {"date": started[:10], "calibrated_utc": started,
                     "run_uid": run.get("run_uid"), "seed": run.get("seed")},
        "body_frame": BODY_FRAME,
        "models": MODELS,
        "ieu": {"timer_period_s": timer_period_s,
                "note": "S2^T: seconds per IEU timer pulse (nominal, from the oscillator)"},
        "constants": constants,
        "covariance": {"kind": kind, "estimator": estimator, "order": order,
                       "matrix": [[float(x) for x in row] for row in mat],
                       "correlated_rows": full_rows, "note": note},
    }


def calibration_file_document(out: Path, calib: CalibrationResults, timer_period_s: float,
                              data: CalibrationData | None = None,
                              noise: NoiseSpec | None = None,
                              estimator: str = "closed-form",
                              series: Mapping[int, list[dict]] | None = None
                              ) -> dict[str, Any]:
    """DIR/calibration.json's document: full covariance when ``data`` (the calibration's
    input) is given and its Jacobian can be taken, else the diagonal of the predicted
    sigmas."""
    cov = None
    why = ""
    if data is not None:
        try:
            cov = calibration_covariance(data, noise or NoiseSpec(), estimator, series)
        except (ValueError, np.linalg.LinAlgError) as e:  # a design it cannot cover
            why = f"diagonal: the full covariance could not be taken ({e})"
    return calibration_document(out, calib, timer_period_s, cov, why, estimator)


def day_calibration_document(out: Path, calib: CalibrationResults, cfg: StationConfig,
                             data: DayData, plan: DayPlan, site: Site, noise: NoiseSpec
                             ) -> dict[str, Any]:
    """The calibration file of `station day`'s run in ``out``, with the full covariance
    from the day's data (diagonal when the data cannot give it)."""
    osc = cfg.oscillator
    try:
        cd: CalibrationData | None = calibration_data(data, plan, site)
    except ValueError:  # no survey (a partial day): the sheet's sigmas only
        cd = None
    return calibration_file_document(out, calib, osc.s2_divider / osc.nominal_hz, cd, noise,
                                     plan.options.estimator, data.nonlinearity)


def write_day_calibration(out: Path, calib: CalibrationResults, cfg: StationConfig,
                          data: DayData, plan: DayPlan, site: Site, noise: NoiseSpec) -> Path:
    """What `station align` calls after its day: DIR/calibration.json
    (``day_calibration_document``)."""
    path = out / FILE_NAME
    write_json(path, day_calibration_document(out, calib, cfg, data, plan, site, noise))
    return path


# ----- reading -----
@dataclass(frozen=True)
class CalibrationFile:
    """A loaded calibration file: constants (value, sigma), covariance and the IEU timer."""

    path: Path
    doc: dict[str, Any]
    values: dict[Row, float]
    sigmas: dict[Row, float]
    timer_period_s: float
    order: list[Row]
    covariance: np.ndarray

    def require(self, rows: list[Row]) -> None:
        """CalibrationFileError naming every constant the caller needs that the file lacks."""
        missing = [f"{i} {p}" for i, p in rows if (i, p) not in self.values]
        if missing:
            raise CalibrationFileError(f"{self.path}: constants: no value for "
                                       + ", ".join(missing))


def _need(doc: Mapping[str, Any], key: str, kind: type | tuple[type, ...], path: Path,
          where: str = "") -> Any:
    if key not in doc:
        raise CalibrationFileError(f"{path}: {where}{key}: missing")
    v = doc[key]
    if not isinstance(v, kind) or isinstance(v, bool) and kind is not bool:
        raise CalibrationFileError(f"{path}: {where}{key}: wrong type {type(v).__name__}")
    return v


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def parse(doc: Any, path: Path) -> CalibrationFile:
    """Check ``doc`` structurally (what the JSON Schema says, and consistency) and load it."""
    if not isinstance(doc, dict):
        raise CalibrationFileError(f"{path}: not a JSON object")
    if _need(doc, "format", str, path) != FORMAT:
        raise CalibrationFileError(f"{path}: format: {doc['format']!r} is not {FORMAT!r}")
    ver = _need(doc, "schema_version", int, path)
    if ver not in READABLE_VERSIONS:
        raise CalibrationFileError(f"{path}: schema_version: {ver} is not supported "
                                   f"(this station reads {READABLE_VERSIONS})")
    unit = _need(doc, "unit", dict, path)
    if not unit or not all(isinstance(v, str) for v in unit.values()):
        raise CalibrationFileError(f"{path}: unit: expected the unit's serials")
    val = _need(doc, "validity", dict, path)
    for k in ("date", "run_uid"):
        _need(val, k, str, path, "validity.")
    _need(doc, "body_frame", dict, path)
    ieu = _need(doc, "ieu", dict, path)
    s2 = _need(ieu, "timer_period_s", (int, float), path, "ieu.")
    if not _number(s2) or s2 <= 0:
        raise CalibrationFileError(f"{path}: ieu.timer_period_s: must be a positive number")
    consts = _need(doc, "constants", list, path)
    values: dict[Row, float] = {}
    sigmas: dict[Row, float] = {}
    for n, c in enumerate(consts):
        where = f"constants[{n}]."
        if not isinstance(c, dict):
            raise CalibrationFileError(f"{path}: constants[{n}]: not an object")
        inst = _need(c, "instrument", str, path, where)
        par = _need(c, "parameter", str, path, where)
        if par not in INSTRUMENTS.get(inst, ()):
            raise CalibrationFileError(f"{path}: {where}parameter: unknown constant "
                                       f"{inst} {par}")
        _need(c, "units", str, path, where)
        for k in ("value", "sigma"):
            if k not in c:
                raise CalibrationFileError(f"{path}: {where}{k}: missing")
            if c[k] is not None and not _number(c[k]):
                raise CalibrationFileError(f"{path}: {where}{k} ({inst} {par}): "
                                           "not a finite number")
        if c["sigma"] is not None and c["sigma"] < 0:
            raise CalibrationFileError(f"{path}: {where}sigma ({inst} {par}): negative")
        if c["value"] is not None:
            values[(inst, par)] = float(c["value"])
            if c["sigma"] is not None:
                sigmas[(inst, par)] = float(c["sigma"])
    cv = _need(doc, "covariance", dict, path)
    kind = _need(cv, "kind", str, path, "covariance.")
    if kind not in ("full", "diagonal"):
        raise CalibrationFileError(f"{path}: covariance.kind: {kind!r} is not full or diagonal")
    order_raw = _need(cv, "order", list, path, "covariance.")
    order: list[Row] = []
    for x in order_raw:
        if (not isinstance(x, list) or len(x) != 2
                or tuple(x) not in values):
            raise CalibrationFileError(f"{path}: covariance.order: {x!r} is not a constant "
                                       "with a value")
        order.append((str(x[0]), str(x[1])))
    mat_raw = _need(cv, "matrix", list, path, "covariance.")
    n = len(order)
    if len(mat_raw) != n or any(not isinstance(r, list) or len(r) != n
                                or not all(_number(v) for v in r) for r in mat_raw):
        raise CalibrationFileError(f"{path}: covariance.matrix: expected {n} x {n} numbers "
                                   "(one row and column per covariance.order)")
    mat = np.array(mat_raw, dtype=float).reshape(n, n)
    scale = np.sqrt(np.outer(np.abs(np.diag(mat)), np.abs(np.diag(mat))))
    if n and (np.any(np.abs(mat - mat.T) > 1e-9 * scale) or np.any(np.diag(mat) < 0)):
        raise CalibrationFileError(f"{path}: covariance.matrix: not symmetric with a "
                                   "non-negative diagonal")
    return CalibrationFile(path, doc, values, sigmas, float(s2), order, mat)


def load(path: Path) -> CalibrationFile:
    """Read and check a calibration file (CalibrationFileError naming the file and field)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise CalibrationFileError(f"{path}: no such calibration file") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise CalibrationFileError(f"{path}: not JSON ({e})") from None
    return parse(doc, path)
