"""Expected reduced data (rates) from instrument coefficients and position geometry.

Used to carry orientation errors into the data (the error propagation's d(data)/d(rotation));
the estimator itself never calls it.

Gyro k (Chart IV-2), deg/hr: w.G + R + B_I a.G + B_O a.O + B_S a.S + C_II (a.G)^2
+ C_SS (a.S)^2 + C_IS (a.G)(a.S) + C_OS (a.O)(a.S) + C_IO (a.G)(a.O) + Q_II (w.G)^2
+ Q_IS (w.G)(w.S), a in g and w in deg/hr; pulses/s = that / 3600 / DeltaPhi(deg/pulse). The
J term vanishes at rest and over whole turns.

Static (positions 7-15): a = g u, w = W cos(lambda) u + W sin(lambda) n, u and n the body
components of up and north.

Turning (positions 1-6), averaged over whole turns about r = R1 (body): the inertial rate
along r is w_R = 3600 w_T + ``Constants.w_along_r1`` (R1 points south, -W sin(lambda) when
level); gravity and the vertical Earth rate W cos(lambda) turn about r together, so
<x.a> = g sin(e) (x.r) with e R1's elevation (zero when level),
<(a.X)(a.Y)> = (g^2/2)(X.Y - (X.r)(Y.r)) (e^2 terms dropped),
<(w.X)(w.Y)> = w_R^2 (X.r)(Y.r) + (W cos^2/2)(X.Y - (X.r)(Y.r)).

Accelerometer k (Chart IV-1): f2 - f1 = D1 (u + D0 + D2 u^2 + D3 u^3), u = g A.up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from procedures.isu.calibration.inputs import Constants
from procedures.isu.calibration.vectors import cross3, norm3

E3 = np.eye(3)
NOMINAL_AXES = (  # (G, O, S) of gyros 1, 2, 3 in body components (DOMAIN.md, Chart III-9)
    (E3[0], E3[2], -E3[1]),
    (E3[1], E3[0], -E3[2]),
    (E3[2], E3[0], E3[1]),
)
GYRO_TERMS = ("R", "B_I", "B_O", "B_S", "C_II", "C_SS", "C_IS", "C_OS", "C_IO", "Q_II", "Q_IS")


def lab_axes(k: int, g_b: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gyro k's (G, O, S) as the laboratory realizes them: G along ``g_b`` (the measured
    G.B_j; nominal when None), O the nominal O squared up to it, S = G x O. No position
    measures a turn of O and S about G, so the calibration's B_O, B_S and compliances are
    defined on these axes."""
    g0, o0, _ = NOMINAL_AXES[k - 1]
    G = g0.copy() if g_b is None else np.asarray(g_b, dtype=float)
    G = G / norm3(G)
    O = o0 - (o0 @ G) * G  # noqa: E741
    O = O / norm3(O)  # noqa: E741
    return G, O, cross3(G, O)


def lab_frames(g_rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``lab_axes`` of gyros 1-3 from the rows [G_k.B_j]: the rows G_k, O_k, S_k."""
    axes = [lab_axes(k, g_rows[k - 1]) for k in (1, 2, 3)]
    return (np.array([x[0] for x in axes]), np.array([x[1] for x in axes]),
            np.array([x[2] for x in axes]))


@dataclass
class GyroModel:
    dphi_deg: float  # deg/pulse
    G: np.ndarray
    O: np.ndarray  # noqa: E741 - the report's symbol
    S: np.ndarray
    coef: dict[str, float]  # GYRO_TERMS, lab units

    @staticmethod
    def from_estimates(k: int, est: dict[str, float | None]) -> GyroModel:
        """Linearization point: estimated axis G (nominal if unknown), O and S squared up."""
        gb = [est.get(f"G.B{j}") for j in (1, 2, 3)]
        G, O, S = lab_axes(k, np.array(gb, dtype=float) if None not in gb else None)  # noqa: E741
        dphi = est.get("DeltaPhi")
        coef = {t: float(est.get(t) or 0.0) for t in GYRO_TERMS}
        return GyroModel(float(dphi) if dphi else 3.0 / 3600.0, G, O, S, coef)  # deg/pulse

    def _deg_hr(self, ag: float, ao: float, as_: float, wg: float, ws: float, agg: float,
                ass: float, ags: float, aos: float, ago: float, wgg: float,
                wgs: float) -> float:
        """Indicated rate, deg/hr: the input rate wg plus the model's drift terms."""
        c = self.coef
        return (
            wg
            + c["R"]
            + c["B_I"] * ag
            + c["B_O"] * ao
            + c["B_S"] * as_
            + c["C_II"] * agg
            + c["C_SS"] * ass
            + c["C_IS"] * ags
            + c["C_OS"] * aos
            + c["C_IO"] * ago
            + c["Q_II"] * wgg
            + c["Q_IS"] * wgs
        )

    def _static_args(self, u: np.ndarray, n: np.ndarray, c: Constants) -> tuple[float, ...]:
        a = c.g * u
        w = c.w_cos_lambda * u + c.w_sin_lambda * n
        ag, ao, as_ = a @ self.G, a @ self.O, a @ self.S
        wg, ws = w @ self.G, w @ self.S
        return (ag, ao, as_, wg, ws, ag * ag, as_ * as_, ag * as_, ao * as_, ag * ao, wg * wg,
                wg * ws)

    def static_rate(self, u: np.ndarray, n: np.ndarray, c: Constants) -> float:
        """Pulses/s at rest with up u and north n (body components)."""
        return self._deg_hr(*self._static_args(u, n, c)) / 3600.0 / self.dphi_deg

    def static_terms(self, u: np.ndarray, n: np.ndarray, c: Constants) -> dict[str, float]:
        """d(static_rate)/d(each of GYRO_TERMS): the model is linear in them."""
        return self._terms(self._static_args(u, n, c))

    def turning_rate(self, r: np.ndarray, w_t_deg_s: float, c: Constants) -> float:
        """Pulses/s averaged over whole turns of the table about r (body), w_T in deg/s."""
        return self._deg_hr(*self._turning_args(r, w_t_deg_s, c)) / 3600.0 / self.dphi_deg

    def turning_terms(self, r: np.ndarray, w_t_deg_s: float, c: Constants) -> dict[str, float]:
        """d(turning_rate)/d(each of GYRO_TERMS): the model is linear in them."""
        return self._terms(self._turning_args(r, w_t_deg_s, c))

    def _terms(self, args: tuple[float, ...]) -> dict[str, float]:
        ag, ao, as_, _, _, agg, ass, ags, aos, ago, wgg, wgs = args
        scale = 1.0 / 3600.0 / self.dphi_deg
        return {t: x * scale for t, x in zip(GYRO_TERMS, (1.0, ag, ao, as_, agg, ass, ags,
                                                          aos, ago, wgg, wgs), strict=True)}

    def _turning_args(self, r: np.ndarray, w_t_deg_s: float, c: Constants
                      ) -> tuple[float, ...]:
        wr = 3600.0 * w_t_deg_s + c.w_along_r1
        g2h, w2h = 0.5 * c.g**2, 0.5 * c.w_cos_lambda**2
        G, O, S = self.G, self.O, self.S  # noqa: E741
        gr, orr, sr = G @ r, O @ r, S @ r

        def aa(x: np.ndarray, y: np.ndarray, xr: float, yr: float) -> float:
            return g2h * (x @ y - xr * yr)

        a_r = c.g * math.sin(c.r1_elevation)  # gravity along a tilted R1
        return (
            a_r * gr,
            a_r * orr,
            a_r * sr,
            wr * gr,
            wr * sr,
            aa(G, G, gr, gr),
            aa(S, S, sr, sr),
            aa(G, S, gr, sr),
            aa(O, S, orr, sr),
            aa(G, O, gr, orr),
            wr * wr * gr * gr + w2h * (1.0 - gr * gr),
            wr * wr * gr * sr + w2h * (G @ S - gr * sr),
        )


@dataclass
class AccelModel:
    D1: float
    A: np.ndarray
    D0: float
    D2: float
    D3: float

    @staticmethod
    def from_estimates(k: int, est: dict[str, float | None]) -> AccelModel:
        ab = [est.get(f"A.B{j}") for j in (1, 2, 3)]
        A = np.array(ab, dtype=float) if None not in ab else E3[k - 1].copy()
        A = A / norm3(A)
        return AccelModel(
            float(est.get("D1") or 2000.0),
            A,
            float(est.get("D0") or 0.0),
            float(est.get("D2") or 0.0),
            float(est.get("D3") or 0.0),
        )

    def difference(self, u: np.ndarray, c: Constants) -> float:
        """f2 - f1, pulses/s, with up u (body components)."""
        x = c.g * (self.A @ u)
        return self.D1 * (x + self.D0 + self.D2 * x * x + self.D3 * x**3)

    def difference_terms(self, u: np.ndarray, c: Constants) -> dict[str, float]:
        """d(difference)/d(D1 D0, D1 D2, D1 D3): linear in those products."""
        x = c.g * (self.A @ u)
        return {"b0": 1.0, "b2": x * x, "b3": x**3}
