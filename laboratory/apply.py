"""`station apply`: a calibration file applied to raw IEU pulse counts.

Each IEU sample (alignments/*-ieu.csv: timer, gyro1..3 net pulses, A1S1..A3S2 string counts)
becomes a compensated angular increment (rad) and a specific force (m/s^2), both in the body
frame B, by inverting the instrument models:

* accelerometer (Chart IV-1): the string difference rate r = (S2 - S1)/dt solves
  r = D1 (u + D0 + D2 u^2 + D3 u^3) for u = a.A_k / g (Newton from the linear solution);
  then a = g [A_k.B_j]^-1 u;
* gyro (Chart IV-2): m = pulses DeltaPhi / dt - R is w.G plus the g-dependent terms (a.G,
  a.O, a.S from a in B and the gyro axes) and the rate terms Q_II (w.G)^2 + Q_IS (w.G)(w.S);
  w.G is found by fixed-point iteration (w.S from the previous body rate), then
  w = [G_k.B_j]^-1 (w.G). O and S are the nominal axes squared up to the calibrated G
  (the calibration measures G only; O and S enter only through second-order terms).
  J d(w.O)/dt integrates to the change of w.O over a sample, zero at rest: left out.

Rates and counts are treated as constant over a sample (the IEU's period, a fraction of a
second), as the procedures' Chart III-5/III-9 preprocessing treats an interval.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from laboratory.calfile import CalibrationFile, CalibrationFileError
from procedures.isu.alignment.estimation import G0
from procedures.isu.calibration.forward import lab_frames
from station.errors import UseError

ARCSEC = np.pi / (180.0 * 3600.0)
DEG_HR = np.pi / 180.0 / 3600.0  # rad/s per deg/hr
RAW_COLUMNS = ("timer", "gyro1", "gyro2", "gyro3",
               "A1S1", "A1S2", "A2S1", "A2S2", "A3S1", "A3S2")
GYRO_USED = ("DeltaPhi", "G.B1", "G.B2", "G.B3", "R", "B_I", "B_O", "B_S", "C_II", "C_SS",
             "C_IS", "C_OS", "C_IO", "Q_II", "Q_IS")
ACCEL_USED = ("D1", "A.B1", "A.B2", "A.B3", "D0", "D2", "D3")
NEEDED = ([(f"gyro{k}", p) for k in (1, 2, 3) for p in GYRO_USED]
          + [(f"accel{k}", p) for k in (1, 2, 3) for p in ACCEL_USED])
NEWTON_STEPS = 6
RATE_ITERATIONS = 4


class RawFileError(UseError, ValueError):
    """A raw IEU sample file that cannot be read (the message names the file and column)."""


@dataclass(frozen=True)
class RawCounts:
    """Raw IEU samples: timer counts (n,), gyro net pulses (n, 3), string counts (n, 6),
    and whatever identifying columns the file had (seq, t_s), kept for the output."""

    timer: np.ndarray
    gyro: np.ndarray
    strings: np.ndarray
    extra: dict[str, np.ndarray]


@dataclass(frozen=True)
class Compensated:
    """Per sample: its length dt (s), angular increment in B (rad), specific force in B
    (m/s^2)."""

    dt: np.ndarray
    dtheta: np.ndarray
    force: np.ndarray

    @property
    def rate(self) -> np.ndarray:
        """Mean body rate of each sample, rad/s."""
        return self.dtheta / self.dt[:, None]


def read_raw(path: Path) -> RawCounts:
    """The IEU sample CSV (columns by its header, RAW_COLUMNS required)."""
    path = Path(path)
    try:
        with path.open(newline="") as f:
            rows = list(csv.DictReader(f))
    except FileNotFoundError:
        raise RawFileError(f"{path}: no such raw sample file") from None
    if not rows:
        raise RawFileError(f"{path}: no samples")
    missing = [c for c in RAW_COLUMNS if c not in rows[0]]
    if missing:
        raise RawFileError(f"{path}: missing column(s) {', '.join(missing)}")
    cols: dict[str, np.ndarray] = {}
    for c in rows[0]:
        try:
            cols[c] = np.array([float(r[c]) for r in rows])
        except (TypeError, ValueError):
            raise RawFileError(f"{path}: column {c}: not a number in every row") from None
    if np.any(cols["timer"] <= 0):
        raise RawFileError(f"{path}: column timer: a sample with no timer pulses")
    extra = {c: v for c, v in cols.items() if c not in RAW_COLUMNS}
    return RawCounts(cols["timer"], np.column_stack([cols[f"gyro{k}"] for k in (1, 2, 3)]),
                     np.column_stack([cols[c] for c in RAW_COLUMNS[4:]]), extra)


def _vec(cal: CalibrationFile, inst: str, par: str) -> np.ndarray:
    return np.array([cal.values[(f"{inst}{k}", par)] for k in (1, 2, 3)])


def _axes(cal: CalibrationFile, inst: str, prefix: str) -> np.ndarray:
    """[X_k.B_j] (rows: instrument k), the calibrated input axes, normalised."""
    m = np.array([[cal.values[(f"{inst}{k}", f"{prefix}.B{j}")] for j in (1, 2, 3)]
                  for k in (1, 2, 3)])
    return m / np.linalg.norm(m, axis=1, keepdims=True)


def specific_force(cal: CalibrationFile, strings: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Chart IV-1 inverted: specific force in B (n, 3), m/s^2."""
    d1, d0 = _vec(cal, "accel", "D1"), _vec(cal, "accel", "D0")
    d2, d3 = _vec(cal, "accel", "D2"), _vec(cal, "accel", "D3")
    s = np.asarray(strings, dtype=float)
    r = (s[:, 1::2] - s[:, 0::2]) / dt[:, None] / d1  # u + D0 + D2 u^2 + D3 u^3
    u = r - d0
    for _ in range(NEWTON_STEPS):
        f = u + d0 + d2 * u * u + d3 * u**3 - r
        u = u - f / (1.0 + 2.0 * d2 * u + 3.0 * d3 * u * u)
    return G0 * u @ np.linalg.inv(_axes(cal, "accel", "A")).T


def gyro_frames(cal: CalibrationFile) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Calibrated G axes and the nominal O, S squared up to them (rows: gyro k, in B): the
    axes the calibration's B and C are defined on (``forward.lab_frames``)."""
    return lab_frames(_axes(cal, "gyro", "G"))


def body_rate(cal: CalibrationFile, pulses: np.ndarray, dt: np.ndarray,
              force: np.ndarray) -> np.ndarray:
    """Chart IV-2 inverted: mean body rate of each sample (n, 3), deg/hr."""
    gk = {p: _vec(cal, "gyro", p) for p in GYRO_USED if not p.startswith("G.")}
    g_ax, o_ax, s_ax = gyro_frames(cal)
    a = force / G0  # g
    ag, ao, as_ = a @ g_ax.T, a @ o_ax.T, a @ s_ax.T
    dphi = gk["DeltaPhi"] * 3600.0  # arcsec/pulse; an arcsec per second is a deg/hr
    m = np.asarray(pulses, dtype=float) * dphi / dt[:, None] - gk["R"] - (
        gk["B_I"] * ag + gk["B_O"] * ao + gk["B_S"] * as_
        + gk["C_II"] * ag * ag + gk["C_SS"] * as_ * as_ + gk["C_IS"] * ag * as_
        + gk["C_OS"] * ao * as_ + gk["C_IO"] * ag * ao)
    g_inv = np.linalg.inv(g_ax)
    wg = m
    for _ in range(RATE_ITERATIONS):
        w = wg @ g_inv.T
        ws = w @ s_ax.T
        wg = m - gk["Q_II"] * wg * wg - gk["Q_IS"] * wg * ws
    return wg @ g_inv.T


def apply_calibration(cal: CalibrationFile, raw: RawCounts) -> Compensated:
    """Compensated angular increments (rad) and specific forces (m/s^2) in B, per sample."""
    cal.require(NEEDED)
    dt = raw.timer * cal.timer_period_s
    force = specific_force(cal, raw.strings, dt)
    w = body_rate(cal, raw.gyro, dt, force) * DEG_HR
    return Compensated(dt, w * dt[:, None], force)


def write_compensated(path: Path, raw: RawCounts, comp: Compensated) -> None:
    """CSV: the raw file's identifying columns, dt_s, dtheta_B1..3 (rad), f_B1..3 (m/s^2)."""
    names = [*raw.extra, "dt_s", "dtheta_B1_rad", "dtheta_B2_rad", "dtheta_B3_rad",
             "f_B1_mps2", "f_B2_mps2", "f_B3_mps2"]
    with Path(path).open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        for i in range(comp.dt.size):
            w.writerow([*(_cell(v[i]) for v in raw.extra.values()),
                        repr(float(comp.dt[i])), *(repr(float(x)) for x in comp.dtheta[i]),
                        *(repr(float(x)) for x in comp.force[i])])


def _cell(x: float) -> str:
    """A raw identifying value as the raw file wrote it (integers without a point)."""
    return str(int(x)) if float(x).is_integer() else repr(float(x))


__all__ = ["CalibrationFileError", "Compensated", "RawCounts", "RawFileError",
           "apply_calibration", "read_raw", "write_compensated"]
