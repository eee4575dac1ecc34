"""Preprocessing of the IEU data (Charts III-5 and III-9): counts to body-axis integrals.

Inputs per interval of Delta t (K intervals, each the sum of several IEU samples): the net
gyro pulses (Sigma delta)_k, the string counts (Sigma gamma)_k1, (Sigma gamma)_k2 and the
timer count (Sigma n2^T). Outputs: int a.B_k dt (g s) and int omega.B_k dt (arcsec; an
arcsec per second is a deg/hr, so a rate in deg/hr times seconds is arcsec).

Where the printed charts and the instrument models disagree (Charts IV-1 and IV-2 as the
calibration uses them), the model wins and the line says so:

* Chart III-9 divides the gyro pulses by (Delta Phi)_k; Delta Phi is the angle per pulse
  (arcsec/pulse on the Calibration Results Sheet), so the angle is P^G x Delta Phi.
* Chart III-9 prints the Q_IS term as Q_IS (w.G)(a.S); Chart IV-2's model (and the
  simulated gyro) has Q_IS (w.G)(w.S). The model's is used, with w.S from the gyros'
  first-pass rates (next but one). At rest it is about 1e-7 deg/hr either way.
* Q^A and Q^G: the charts print the first-order inverse of the matrix of (A_k.B_j)
  ((G_k.B_j)) that the calibration determines; here that matrix is inverted exactly (the
  difference is of second order in the misalignments, about 0.05 arcsec).
* Chart III-9 takes a.G_k as accelerometer k's a.A_k and a.O_k, a.S_k as the other two
  accelerometers' outputs (the nominal axes, gyro 1's S = -B2, gyro 2's -B3, gyro 3's +B2;
  a (w.S_k) would come from another gyro's rate alike). That is first order in the
  misalignments: B_I of 100 deg/hr/g with axes 600 arcsec apart is 0.3 deg/hr, 7 sigma of
  the gyrocompass's |omega|. Here the body-axis specific
  force and first-pass rate (through Q^A and Q^G) are projected on the calibration's own
  G_k, O_k, S_k (``forward.lab_frames``, the axes its B and C are defined on).
* The J term (J d(w.O)/dt) is not in Chart III-9; on a table at rest it integrates to zero
  over an interval and is left out as the chart leaves it out.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from procedures.isu.calibration.forward import lab_frames
from procedures.isu.sheets import CalibrationResults, scale_factor_arcsec

GYRO_PARAMS = (
    "DeltaPhi", "G.B1", "G.B2", "G.B3", "R", "B_I", "B_O", "B_S", "C_II", "C_SS", "C_IS",
    "C_OS", "C_IO", "Q_II", "Q_IS",
)
ACCEL_PARAMS = ("D1", "A.B1", "A.B2", "A.B3", "D0", "D2", "D3")


class MissingConstants(ValueError):
    """The Calibration Results Sheet lacks constants the alignment needs."""


@dataclass
class Constants:
    """Calibration constants the preprocessing uses, keyed (instrument, parameter)."""

    values: dict[tuple[str, str], float]
    sigmas: dict[tuple[str, str], float] = field(default_factory=dict)
    # correlation of two constants computed together (Chart II-15 step 8), either order;
    # a pair not listed is independent
    correlation: dict[tuple[tuple[str, str], tuple[str, str]], float] = field(
        default_factory=dict)
    # rho_matrix's matrices by their keys, shared by the constants ``perturbed`` makes
    # (they keep the correlation): an error model asks the same few sets again and again
    rho_held: dict[tuple[tuple[str, str], ...], np.ndarray] = field(
        default_factory=dict, repr=False, compare=False)

    def rho(self, a: tuple[str, str], b: tuple[str, str]) -> float:
        """Correlation of the errors of constants a and b (1 when a is b)."""
        if a == b:
            return 1.0
        return self.correlation.get((a, b), self.correlation.get((b, a), 0.0))

    def rho_matrix(self, keys: list[tuple[str, str]]) -> np.ndarray:
        """[rho(a, b)] over ``keys``: ``rho``'s values, set from the listed pairs rather
        than looked up pair by pair (issue 17: 4,356 lookups per error model). Read-only:
        the same matrix serves every later call with these keys."""
        held = self.rho_held.get(tuple(keys))
        if held is not None:
            return held
        at = {k: i for i, k in enumerate(keys)}
        out = np.zeros((len(keys), len(keys)))
        for (a, b), r in self.correlation.items():
            i, j = at.get(a), at.get(b)
            if i is not None and j is not None:
                out[i, j] = r
                if (b, a) not in self.correlation:  # rho(b, a) falls back on (a, b)
                    out[j, i] = r
        np.fill_diagonal(out, 1.0)  # rho(a, a) is 1 whatever the sheet lists
        out.flags.writeable = False
        self.rho_held[tuple(keys)] = out
        return out

    @classmethod
    def from_sheet(cls, sheet: CalibrationResults, gyros: bool) -> Constants:
        """Constants of the accelerometers (and of the gyros if ``gyros``) from Chart II-5.

        Raises MissingConstants naming every row that has no estimate.
        """
        want = [(f"accel{k}", p) for k in (1, 2, 3) for p in ACCEL_PARAMS]
        if gyros:
            want += [(f"gyro{k}", p) for k in (1, 2, 3) for p in GYRO_PARAMS]
        rows = {(r.instrument, r.parameter): r for r in sheet.rows}
        missing = [f"{i} {p}" for i, p in want if rows.get((i, p)) is None
                   or rows[(i, p)].estimate is None]
        if missing:
            raise MissingConstants(
                "Calibration Results Sheet lacks " + ", ".join(missing)
                + " (a full calibration, Chart II-16, determines them)"
            )
        values = {k: float(rows[k].estimate) for k in want}  # type: ignore[arg-type]
        sigmas = {k: float(rows[k].sigma or 0.0) for k in want}
        corr: dict[tuple[tuple[str, str], tuple[str, str]], float] = {}
        if sheet.correlation is not None:
            names = [(r.split(" ")[0], r.split(" ")[-1]) for r in sheet.correlation.rows]
            wanted = set(want)
            for i, a in enumerate(names):
                for j in range(i + 1, len(names)):
                    b, r = names[j], sheet.correlation.matrix[i][j]
                    if r and a in wanted and b in wanted:
                        corr[(a, b)] = float(r)
        return cls(values, sigmas, corr)

    def perturbed(self, key: tuple[str, str], delta: float) -> Constants:
        v = dict(self.values)
        v[key] += delta
        return Constants(v, self.sigmas, self.correlation, self.rho_held)

    def get(self, inst: str, k: int, par: str) -> float:
        return self.values[(f"{inst}{k}", par)]

    def vector(self, inst: str, par: str) -> np.ndarray:
        return np.array([self.get(inst, k, par) for k in (1, 2, 3)])

    def flat(self, inst: str, prefix: str) -> tuple[float, ...]:
        """``matrix`` row by row as a tuple (a cache key)."""
        v = self.values
        return tuple(v[(f"{inst}{k}", f"{prefix}.B{j}")] for k in (1, 2, 3) for j in (1, 2, 3))

    def matrix(self, inst: str, prefix: str) -> np.ndarray:
        """[X_k . B_j] (rows k = instrument, columns j = body axis): (Q^X)^-1."""
        return np.array(
            [[self.get(inst, k, f"{prefix}.B{j}") for j in (1, 2, 3)] for k in (1, 2, 3)]
        )


def string_differences(strings: np.ndarray) -> np.ndarray:
    """P_k^A = (Sigma gamma)_k2 - (Sigma gamma)_k1 from columns A1S1, A1S2, ..., A3S2."""
    s = np.asarray(strings, dtype=float)
    return s[:, 1::2] - s[:, 0::2]


def accel_integrals(p_a: np.ndarray, dt: np.ndarray, c: Constants) -> tuple[np.ndarray, ...]:
    """Chart III-5: (int a.B_k dt, int a.A_k dt, mean a.A_k before D2, D3), K x 3, g s / g.

    ``p_a``: P_k^A (K x 3 counts); ``dt``: interval lengths S2^T (Sigma n2^T) (K,), s.
    """
    dt = np.asarray(dt, dtype=float)[:, None]
    d1, d0 = c.vector("accel", "D1"), c.vector("accel", "D0")
    d2, d3 = c.vector("accel", "D2"), c.vector("accel", "D3")
    raw = np.asarray(p_a, dtype=float) / d1 - d0 * dt  # [(a.A_k) dt]
    u = raw / dt  # (a.A_k)
    int_a = raw - d2 * u * u * dt - d3 * u**3 * dt
    q_a = _inverse(c.flat("accel", "A"))  # Q^A
    return int_a @ q_a.T, int_a, u


# the gyro parameters other than the axes, and their constants' keys for gyros 1, 2, 3
_NOT_AXES = tuple(p for p in GYRO_PARAMS if not p.startswith("G."))
_NOT_AXES_KEYS = tuple(tuple((f"gyro{k}", p) for k in (1, 2, 3)) for p in _NOT_AXES)


@lru_cache(maxsize=64)
def _inverse(m: tuple[float, ...]) -> np.ndarray:
    """Q^X of the 3 x 3 [X_k.B_j] given row by row (an error model's perturbation passes
    move one constant at a time: most of them keep the axes)."""
    return np.linalg.inv(np.array(m).reshape(3, 3))


@lru_cache(maxsize=64)
def _gyro_frames(g: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Rows G_k, O_k, S_k of the calibration's axes (``forward.lab_frames``) and Q^G, from
    [G_k.B_j] given row by row."""
    return (*lab_frames(np.array(g).reshape(3, 3)), _inverse(g))


def gyro_integrals(p_g: np.ndarray, dt: np.ndarray, a_a: np.ndarray, c: Constants) -> np.ndarray:
    """Chart III-9: int omega.B_k dt (K x 3, arcsec) from the net pulses ``p_g`` (K x 3).

    ``a_a``: the mean a.A_k of each interval (g), from ``accel_integrals``; the g terms take
    its body-axis vector along the gyros' G, O, S (see the top).
    """
    dt = np.asarray(dt, dtype=float)[:, None]
    values = c.values  # each parameter's three gyros, gathered in one array
    g = dict(zip(_NOT_AXES, np.array([[values[k] for k in keys] for keys in _NOT_AXES_KEYS]),
                 strict=True))
    dphi = scale_factor_arcsec(g["DeltaPhi"])  # Chart II-5's deg/pulse, in arcsec/pulse
    raw = np.asarray(p_g, dtype=float) * dphi - g["R"] * dt  # [(w.G_k) dt], arcsec
    w_g = raw / dt  # (w.G_k), deg/hr
    g_rows, o_rows, s_rows, q_g = _gyro_frames(c.flat("gyro", "G"))
    a_b = np.asarray(a_a, dtype=float) @ _inverse(c.flat("accel", "A")).T
    a_g, a_o, a_s = a_b @ g_rows.T, a_b @ o_rows.T, a_b @ s_rows.T  # a_b: a.B_j, g
    w_s = (w_g @ q_g.T) @ s_rows.T  # Chart IV-2's (w.S_k), from the first-pass body rate
    rate = (
        g["B_I"] * a_g + g["B_O"] * a_o + g["B_S"] * a_s
        + g["C_II"] * a_g**2 + g["C_SS"] * a_s**2
        + g["C_IS"] * a_g * a_s + g["C_OS"] * a_o * a_s + g["C_IO"] * a_g * a_o
        + g["Q_II"] * w_g**2 + g["Q_IS"] * w_g * w_s  # Chart III-9 prints (w.G)(a.S): see top
    )
    int_w = raw - rate * dt
    return int_w @ q_g.T  # Q^G
