"""Gravity estimators of level and gyrocompass alignment (Charts I-9, I-10, III-6, III-10).

The estimation routine of Part III turns K consecutive accelerometer integrals into the body
components of g at a time t* as ``g_hat = M X + b`` (Chart III-6). The simple average has
b = 0 and M made of rows of 1/(K dt) (Chart III-6; the 6 x 6K version for the gyrocompass,
Chart III-10). The posterior mean ("instantaneous") estimator takes M and b from the
parameter evaluation of Part I, Section 3, whose chart (I-9) survives only in pieces: the
intermediate covariances and the last two lines (M = -A^-1 B, b = a1 + A^-1 B a2, A^-1 the
covariance of the estimate) are printed, the definitions of Sigma_Z, A, B, a1, a2 are not.
This module rebuilds them from the measurement model below; the printed pieces and the V
matrix of Chart I-10 fit it term by term.

Units and conventions
---------------------
* SI throughout: m/s^2 for g, sigma_g and phi_alpha, phi_n; rad and rad^2 for angles and
  phi_theta; seconds for dt, lags and eps_t. (The report writes ft/s^2.)
* Earth frame E1 = up, E2 = east, E3 = north. The prior attitude ``T1`` is given like the
  T of Part III: ``T1[i, k] = E_i . B_k``, the columns are the body axes in earth
  components (T^EB in the lab's X_i . Y_j convention). Chart I-9 calls its T~1 "an estimate
  of T^EB" but every printed use of it (Sigma_g~ = T~1 D T~1^T and the V entries
  g~ (T~1)_k3, -g~ (T~1)_k2 in the row of body axis k) treats it as the matrix taking earth
  components to body components, i.e. rows = body axes. Where the chart writes T~1, this
  module therefore uses ``T1.T``.

Measurement model
-----------------
At rest, the specific force is g along up. The pier turns the ISU by a small rotation
eps(t) = (0, theta_E(t), theta_N(t)) in earth components (the simulator's ``eps``), so a body
axis becomes B_k + eps x B_k and

    g . B_k(t) = g U.B_k + g B_k.(U x eps) = g0_k + p_k theta_E(t) + q_k theta_N(t),

with p_k = g N.B_k and q_k = -g E.B_k (U x E = N, U x N = -E). g0 is the untilted vector
(unknown magnitude and unknown vertical); the tilt terms are linearised about the prior, so
p = g~ T1[2, :], q = -g~ T1[1, :]; the neglected part is of order sigma_theta times the
tilt. The prior on g0 has mean a1 = g~ T1[0, :] (the body components of g~ U) and
covariance Sigma_g~ = T1^T diag(sigma_g^2, g~^2 sigma_theta^2, g~^2 sigma_theta^2) T1:
sigma_g along up, g~ sigma_theta along each horizontal earth axis.

Accelerometer k over interval j, [(j-1) dt, j dt], integrates the specific force plus the
floor's translational acceleration alpha_k(t) and the instrument noise n_k(t):

    X_kj = dt g0_k + p_k Theta_E,j + q_k Theta_N,j + N_kj,   Theta_a,j = int_j theta_a dt,

and the quantity wanted is y = g_B(t*) = g0 + p theta_E(t*) + q theta_N(t*), at
t* = K dt + eps_t. X is stacked axis by axis, X[k K + j] (Chart III-6).

Second moments (the intermediate quantities of Chart I-9)
--------------------------------------------------------
All noises are stationary, zero mean, independent of each other and of g0; alpha and n are
independent between axes with the same covariance on each (Sigma_N block diagonal); the two
tilt components have covariances phi_EE, phi_NN and a cross covariance phi_EN, taken even
in the lag (the chart has one phi_theta "per horizontal axis": phi_EE = phi_NN,
phi_EN = 0). For a stationary x with covariance phi, the integrals over two intervals m
steps apart have covariance

    int_0^dt int_0^dt phi(s' - s + m dt) ds ds' = int_{-dt}^{dt} (dt - |u|) phi(u + m dt) du,

which is the printed (Sigma_alpha)_ij, (Sigma_n)_ij and (Sigma_phiphi)_1j with m = j - i
(the matrices are symmetric Toeplitz, so the first row printed for Sigma_phiphi is all
of it). The point value at t* and an interval integral have covariance
c_j = int_0^dt phi(u + (j-1) dt - K dt - eps_t) du, as printed, and c0 = phi_theta(0) (printed
"phi_0(0)"). Sigma_N = blockdiag(Sigma_n + Sigma_alpha) over the three axes, as printed.

Chart I-10 and the posterior mean
---------------------------------
Collect the independent sources in Z = (g0, N, theta_E(t*), Theta_E, theta_N(t*), Theta_N)
(sizes 3, 3K, 1, K, 1, K: the numbers at the edge of the printed V). Their covariance is

    Sigma_Z = blockdiag(Sigma_g~, Sigma_N, Sigma_theta),
    Sigma_theta = [[C_EE, C_EN], [C_EN, C_NN]],  C_ab = [[c0_ab, c_ab^T], [c_ab, Sigma_phiphi_ab]],

and (y, X) = V Z with V the matrix of Chart I-10: rows 1-3 are [I3, 0, p, 0, q, 0]; the K
rows of axis k are [dt e_k^T (in every row), the k-th K x K identity of N, 0, p_k I_K, 0,
q_k I_K]. (y, X) is Gaussian with mean (a1, a2), a2 = dt (a1_1 1_K, a1_2 1_K, a1_3 1_K),
and covariance W = V Sigma_Z V^T. Write its inverse in blocks,

    W^-1 = [[A, B], [B^T, C]],   A: 3 x 3,  B: 3 x 3K.

The density of (y, X) is then proportional to exp(-1/2 [(y-a1)^T A (y-a1) + 2 (y-a1)^T B
(X-a2) + ...]); as a function of y it is the Gaussian with covariance A^-1 and mean
a1 - A^-1 B (X - a2). So the posterior mean is M X + b with

    M = -A^-1 B,  b = a1 + A^-1 B a2,  A^-1 = error covariance of the estimate,

exactly the two printed output lines and the printed note. ``chart_i9_quantities`` builds
these matrices literally (for checking, K small to moderate); ``posterior_level`` computes
the same numbers through the equivalent Schur complement (A^-1 = S_yy - S_yX S_XX^-1 S_Xy,
-A^-1 B = S_yX S_XX^-1 with S the blocks of W), with one Cholesky factor of the 3K x 3K S_XX.

The simple average's error is M X - y with the M of Chart III-6 and b = 0; it is unbiased
(M a2 = a1) and does not depend on the prior (M applied to dt g0 1 gives g0 back), but it
pays for the tilt's motion between the middle of the record and t*. Its error covariance is
M S_XX M^T - M S_Xy - S_yX M^T + S_yy (``covariance_of_average``); the posterior mean's is
never larger, being the best estimator that is affine in X.

Covariance tables
-----------------
Chart I-9 takes the covariance functions as tables. A ``CovarianceTable`` is lags (from 0,
increasing, seconds) and values, read by linear interpolation, with an optional white part
``white`` = q: phi(tau) = q delta(tau) + table(tau), q being the two-sided spectral density
(units of phi times seconds), so that its integral over an interval of length dt has
variance q dt (the accelerometer noise of the lab: q = (10 micro-g)^2 per Hz). Beyond its
last lag a table is zero if ``zero_beyond`` is set; otherwise it must reach every lag the
computation asks for. The integrals are composite Simpson sums on nodes spaced like the table
(every node on a knot when dt is a multiple of the table spacing), as Chart I-9 suggests.
``tables_from_noise_spec`` builds the three tables from the lab's ``NoiseSpec``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import TypedDict, Unpack

import numpy as np
from numpy.typing import ArrayLike
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from procedures.isu.calibration.noise_spec import ARCSEC, NoiseSpec

G0 = 9.80665  # m/s^2, the unit "g" of the lab's specifications
MICRO_G = 1e-6 * G0
MAX_NODES = 20000  # Simpson subintervals per dt, at most
_CHUNK = 4_000_000  # lag evaluations per block of the Toeplitz integrals
Row3 = tuple[float, float, float]
# lags -> the covariance functions at them, one array per function (same shape as the lags)
LagFunctions = Callable[[np.ndarray], tuple[np.ndarray, ...]]


# ---------------------------------------------------------------------------------------------
# Tables
# ---------------------------------------------------------------------------------------------
class _Model(BaseModel):
    model_config = ConfigDict(defer_build=True, extra="forbid", frozen=True, allow_inf_nan=False)


def _check_lags(lags: tuple[float, ...]) -> tuple[float, ...]:
    if lags[0] != 0.0:
        raise ValueError("a covariance table starts at lag 0")
    if any(b <= a for a, b in zip(lags, lags[1:], strict=False)):
        raise ValueError("table lags must increase")
    return lags


class CovarianceTable(_Model):
    """phi(tau) = white * delta(tau) + the tabulated values, linear between the lags (even)."""

    lags_s: tuple[float, ...] = Field(min_length=1, description="lags from 0, increasing, s")
    values: tuple[float, ...] = Field(min_length=1, description="phi at the lags")
    white: float = Field(0.0, ge=0, description="two-sided spectral density q of a white part")
    zero_beyond: bool = Field(False, description="zero past the last lag (else it must reach)")

    @field_validator("lags_s")
    @classmethod
    def _lags(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        return _check_lags(v)

    @model_validator(mode="after")
    def _same_length(self) -> CovarianceTable:
        if len(self.values) != len(self.lags_s):
            raise ValueError("lags_s and values differ in length")
        return self

    @cached_property
    def _arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(self.lags_s, dtype=float), np.asarray(self.values, dtype=float)

    @property
    def spacing(self) -> float | None:
        """Smallest lag step of the table (None for a single lag)."""
        lags = self._arrays[0]
        return float(np.min(np.diff(lags))) if lags.size > 1 else None

    @property
    def has_table(self) -> bool:
        return bool(np.any(self._arrays[1] != 0.0))

    def evaluate(self, tau: ArrayLike, name: str = "table") -> np.ndarray:
        """The tabulated (non-white) part at lags tau (any shape)."""
        lags, vals = self._arrays
        return _interp(np.abs(np.asarray(tau, dtype=float)), lags, vals, self.zero_beyond, name)


class TiltCovarianceTable(_Model):
    """phi_theta per horizontal axis (rad^2): east-east, north-north and east-north.

    ``north`` defaults to ``east``, ``cross`` to zero (Chart I-9: one function per axis).
    The cross covariance E[theta_E(t) theta_N(t + tau)] is taken even in tau.
    """

    lags_s: tuple[float, ...] = Field(min_length=1)
    east: tuple[float, ...] = Field(min_length=1)
    north: tuple[float, ...] | None = None
    cross: tuple[float, ...] | None = None
    zero_beyond: bool = False

    @field_validator("lags_s")
    @classmethod
    def _lags(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        return _check_lags(v)

    @model_validator(mode="after")
    def _same_length(self) -> TiltCovarianceTable:
        n = len(self.lags_s)
        for name in ("east", "north", "cross"):
            v = getattr(self, name)
            if v is not None and len(v) != n:
                raise ValueError(f"phi_theta.{name} and lags_s differ in length")
        return self

    @cached_property
    def _arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        lags = np.asarray(self.lags_s, dtype=float)
        ee = np.asarray(self.east, dtype=float)
        nn = ee if self.north is None else np.asarray(self.north, dtype=float)
        en = np.zeros_like(ee) if self.cross is None else np.asarray(self.cross, dtype=float)
        return lags, ee, nn, en

    @property
    def spacing(self) -> float | None:
        lags = self._arrays[0]
        return float(np.min(np.diff(lags))) if lags.size > 1 else None

    def evaluate(self, tau: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(phi_EE, phi_NN, phi_EN) at lags tau."""
        lags, ee, nn, en = self._arrays
        t = np.abs(np.asarray(tau, dtype=float))
        z = self.zero_beyond
        return (
            _interp(t, lags, ee, z, "phi_theta"),
            _interp(t, lags, nn, z, "phi_theta"),
            _interp(t, lags, en, z, "phi_theta"),
        )


def _interp(
    t: np.ndarray, lags: np.ndarray, vals: np.ndarray, zero_beyond: bool, name: str
) -> np.ndarray:
    last = lags[-1]
    out = np.interp(t, lags, vals)
    if t.size and float(t.max()) > last * (1 + 1e-12) + 1e-12:
        if not zero_beyond:
            raise ValueError(
                f"{name}: the table ends at lag {last:g} s but lag {float(t.max()):g} s is "
                "needed (extend it or set zero_beyond)"
            )
        out = np.where(t > last, 0.0, out)
    return out


# ---------------------------------------------------------------------------------------------
# The inputs of Chart I-8 / I-9
# ---------------------------------------------------------------------------------------------
class LevelParams(_Model):
    """Inputs of the level estimation matrix computations (Chart I-9), SI units."""

    dt: float = Field(gt=0, description="intersample time, s")
    K: int = Field(ge=1, description="number of samples")
    g_tilde: float = Field(gt=0, description="prior estimate of gravity, m/s^2")
    sigma_g: float = Field(ge=0, description="rms error of g_tilde, m/s^2")
    T1: tuple[Row3, Row3, Row3] = Field(
        description="prior T^EB: T1[i][k] = E_i . B_k (columns: body axes in U, E, N)"
    )
    sigma_theta: float = Field(ge=0, description="rms angular error of the prior vertical, rad")
    phi_n: CovarianceTable = Field(description="accelerometer noise, (m/s^2)^2")
    phi_alpha: CovarianceTable = Field(description="translational acceleration noise, (m/s^2)^2")
    phi_theta: TiltCovarianceTable = Field(description="rotational noise, rad^2 per axis")
    eps_t: float = Field(0.0, ge=0, description="prediction time after the last sample, s")

    @field_validator("T1")
    @classmethod
    def _near_rotation(cls, v: tuple[Row3, Row3, Row3]) -> tuple[Row3, Row3, Row3]:
        t = np.asarray(v, dtype=float)
        if np.max(np.abs(t.T @ t - np.eye(3))) > 1e-3 or np.linalg.det(t) < 0:
            raise ValueError("T1 must be (nearly) a proper rotation matrix")
        return v

    @property
    def t_star(self) -> float:
        return self.K * self.dt + self.eps_t

    @property
    def t1(self) -> np.ndarray:
        return np.asarray(self.T1, dtype=float)


# ---------------------------------------------------------------------------------------------
# Integrals of the tables (Chart I-9)
# ---------------------------------------------------------------------------------------------
def _nodes(dt: float, spacing: float | None) -> int:
    """Even number of Simpson subintervals per dt, on the table's knots when they align."""
    if spacing is None:
        return 8
    n = int(math.ceil(dt / spacing - 1e-9))
    n += n % 2
    return int(min(max(n, 8), MAX_NODES))


def _simpson(n: int, h: float) -> np.ndarray:
    w = np.ones(n + 1)
    w[1:-1:2] = 4.0
    w[2:-1:2] = 2.0
    return w * (h / 3.0)


def _toeplitz_rows(evaluate: LagFunctions, dt: float, K: int, n: int) -> np.ndarray:
    """int_{-dt}^{dt} (dt - |u|) phi(u + m dt) du for m = 0..K-1; evaluate returns a tuple."""
    u = np.linspace(-dt, dt, 2 * n + 1)
    w_half = _simpson(n, dt / n)
    w = np.zeros(2 * n + 1)
    w[: n + 1] += w_half
    w[n:] += w_half
    kern = w * (dt - np.abs(u))
    m = np.arange(K, dtype=float) * dt
    rows = max(1, _CHUNK // u.size)
    parts = [
        np.stack([v @ kern for v in evaluate(m[s : s + rows, None] + u[None, :])])
        for s in range(0, K, rows)
    ]
    return np.concatenate(parts, axis=1)


def _point_interval(
    evaluate: LagFunctions, dt: float, K: int, t_star: float, n: int
) -> np.ndarray:
    """c_j = int_0^dt phi(u + (j-1) dt - t*) du, j = 1..K (Chart I-9)."""
    u = np.linspace(0.0, dt, n + 1)
    w = _simpson(n, dt / n)
    lag = (np.arange(K, dtype=float) * dt - t_star)[:, None] + u[None, :]
    return np.stack([v @ w for v in evaluate(lag)])


def toeplitz(row: np.ndarray) -> np.ndarray:
    """The symmetric Toeplitz matrix T[i, j] = row[|i - j|] (a stationary process's Gram)."""
    i = np.arange(len(row))
    return np.asarray(row)[np.abs(i[:, None] - i[None, :])]


def block_diag(*blocks: np.ndarray) -> np.ndarray:
    """The blocks on the diagonal of one matrix, zeros elsewhere."""
    out = np.zeros((sum(b.shape[0] for b in blocks), sum(b.shape[1] for b in blocks)))
    r = c = 0
    for b in blocks:
        out[r:r + b.shape[0], c:c + b.shape[1]] = b
        r, c = r + b.shape[0], c + b.shape[1]
    return out


def noise_gram(table: CovarianceTable, dt: float, K: int, name: str = "phi") -> np.ndarray:
    """Sigma_n or Sigma_alpha of Chart I-9: covariance of the K interval integrals (K x K)."""
    row = np.zeros(K)
    if table.has_table:
        n = _nodes(dt, table.spacing)
        row = _toeplitz_rows(lambda t: (table.evaluate(t, name),), dt, K, n)[0]
    row[0] += table.white * dt
    return toeplitz(row)


@dataclass(frozen=True)
class TiltMoments:
    """Chart I-9 tilt quantities for a in (E, N): c0[a, b], c[a, b] (K,), gram[a, b] (K, K)."""

    c0: np.ndarray  # 2 x 2
    c: np.ndarray  # 2 x 2 x K
    gram: np.ndarray  # 2 x 2 x K x K


def tilt_moments(params: LevelParams) -> TiltMoments:
    tab, dt, K = params.phi_theta, params.dt, params.K
    n = _nodes(dt, tab.spacing)
    rows = _toeplitz_rows(tab.evaluate, dt, K, n)  # (3, K): ee, nn, en
    cs = _point_interval(tab.evaluate, dt, K, params.t_star, n)
    c00 = [float(x[0]) for x in tab.evaluate(np.zeros(1))]
    idx = ((0, 2), (2, 1))  # (E,E)->ee, (E,N)->en, (N,N)->nn
    c0 = np.array([[c00[idx[a][b]] for b in range(2)] for a in range(2)])
    c = np.array([[cs[idx[a][b]] for b in range(2)] for a in range(2)])
    grams = [toeplitz(r) for r in rows]
    gram = np.array([[grams[idx[a][b]] for b in range(2)] for a in range(2)])
    return TiltMoments(c0, c, gram)


# ---------------------------------------------------------------------------------------------
# The joint Gaussian of (y, X)
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Joint:
    """Mean (a1, a2) and covariance blocks of (y, X) = (g_B(t*), the 3K integrals)."""

    a1: np.ndarray  # (3,)
    a2: np.ndarray  # (3K,)
    s_yy: np.ndarray  # (3, 3)
    s_yx: np.ndarray  # (3, 3K)
    s_xx: np.ndarray  # (3K, 3K)


def prior_covariance(params: LevelParams) -> np.ndarray:
    """Sigma_g~ (Chart I-9) with T~1 read as T1^T (see the module docstring)."""
    g, t1 = params.g_tilde, params.t1
    d = np.diag([params.sigma_g**2, (g * params.sigma_theta) ** 2, (g * params.sigma_theta) ** 2])
    return t1.T @ d @ t1


def tilt_coefficients(params: LevelParams) -> np.ndarray:
    """3 x 2 matrix [p q]: body g change per unit tilt about east and about north."""
    g, t1 = params.g_tilde, params.t1
    return np.column_stack((g * t1[2, :], -g * t1[1, :]))


def prior_mean(params: LevelParams) -> tuple[np.ndarray, np.ndarray]:
    """a1 = E[g_B] = g~ (U . B_k), a2 = E[X] = dt a1_k repeated K times per axis."""
    a1 = params.g_tilde * params.t1[0, :]
    return a1, params.dt * np.repeat(a1, params.K)


def noise_block(params: LevelParams) -> np.ndarray:
    """Sigma_n + Sigma_alpha (K x K), one axis of Sigma_N."""
    dt, K = params.dt, params.K
    return noise_gram(params.phi_n, dt, K, "phi_n") + noise_gram(
        params.phi_alpha, dt, K, "phi_alpha"
    )


@lru_cache(maxsize=2)  # a day's two parameter sheets; each of its 3K x 3K blocks asked for thrice
def joint(params: LevelParams) -> Joint:
    """The joint Gaussian of ``params`` (Chart I-9), made once per sheet: the estimator and
    each error covariance of one alignment ask for the same (issue 17: 4 of a day's 6 builds,
    40 ms). Its arrays are shared and read-only."""
    K, dt = params.K, params.dt
    sg = prior_covariance(params)
    cm = tilt_coefficients(params)
    tm = tilt_moments(params)
    a1, a2 = prior_mean(params)
    ones = np.ones(K)
    s_yy = sg + cm @ tm.c0 @ cm.T
    s_yx = dt * np.kron(sg, ones[None, :])
    s_xx = dt * dt * np.kron(sg, np.ones((K, K))) + np.kron(np.eye(3), noise_block(params))
    for a in range(2):
        for b in range(2):
            outer = np.outer(cm[:, a], cm[:, b])
            s_yx += np.kron(outer, tm.c[a, b][None, :])
            s_xx += np.kron(outer, tm.gram[a, b])
    j = Joint(a1, a2, s_yy, s_yx, 0.5 * (s_xx + s_xx.T))
    for arr in (j.a1, j.a2, j.s_yy, j.s_yx, j.s_xx):
        arr.setflags(write=False)  # shared by the cache: a write would change later answers
    return j


# ---------------------------------------------------------------------------------------------
# Estimators
# ---------------------------------------------------------------------------------------------
def simple_average(K: int, dt: float, n_axes: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Chart III-6 (n_axes=3) / III-10 (n_axes=6): M = blockdiag of rows of 1/(K dt), b = 0."""
    M = np.kron(np.eye(n_axes), np.full((1, K), 1.0 / (K * dt)))
    return M, np.zeros(n_axes)


def posterior_level(params: LevelParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Posterior-mean M (3 x 3K), b (3,) and A^-1 (3 x 3), Charts I-9 and I-10."""
    j = joint(params)
    gain = np.linalg.solve(j.s_xx, j.s_yx.T).T  # S_yX S_XX^-1 = -A^-1 B
    cov = j.s_yy - gain @ j.s_yx.T
    return gain, j.a1 - gain @ j.a2, 0.5 * (cov + cov.T)


def error_covariance(M: np.ndarray, b: np.ndarray, params: LevelParams) -> np.ndarray:
    """E[(M X + b - y)(M X + b - y)^T] for any affine estimator of g_B(t*) (3 x 3)."""
    j = joint(params)
    ms = M @ j.s_yx.T
    cov = M @ j.s_xx @ M.T - ms - ms.T + j.s_yy
    bias = M @ j.a2 + b - j.a1
    return 0.5 * (cov + cov.T) + np.outer(bias, bias)


def covariance_of_average(K: int, dt: float, params: LevelParams) -> np.ndarray:
    """Error covariance of the simple average of Chart III-6 under the model of ``params``
    (its noise tables and eps_t; K and dt as given)."""
    p = params.model_copy(update={"K": int(K), "dt": float(dt)})
    M, b = simple_average(int(K), float(dt))
    return error_covariance(M, b, p)


def hybrid_gyrocompass(
    M_level: np.ndarray, b_level: np.ndarray, K: int, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """Chart III-10 hybrid: posterior mean for g (from the level tape), simple average for
    Earth rate; M is 6 x 6K acting on (accelerometer integrals, gyro integrals)."""
    M = np.zeros((6, 6 * K))
    M[:3, : 3 * K] = M_level
    M[3:, 3 * K :] = simple_average(K, dt)[0]
    return M, np.concatenate((np.asarray(b_level, dtype=float), np.zeros(3)))


def predicted_level_sigma_arcsec(cov: np.ndarray, g: ArrayLike) -> tuple[float, float]:
    """Tilt errors (arcsec, 1 sigma) of the vertical implied by a g-estimate covariance.

    ``g``: body components of the specific force (3,). With u = g/|g|, h1 is the horizontal
    part of the body axis nearest the horizontal and h2 = u x h1. A tilt about h1 moves the
    estimate along -h2 and a tilt about h2 along h1, so the result is
    (sqrt(h2' C h2), sqrt(h1' C h1)) / |g|: (about h1, about h2).
    """
    g = np.asarray(g, dtype=float)
    if g.shape != (3,):
        raise ValueError("give g as its three body components")
    cov = np.asarray(cov, dtype=float)
    gm = float(np.linalg.norm(g))
    u = g / gm
    k = int(np.argmin(np.abs(u)))
    h1 = np.eye(3)[k] - u[k] * u
    h1 /= np.linalg.norm(h1)
    h2 = np.cross(u, h1)
    x = math.sqrt(max(float(h2 @ cov @ h2), 0.0)) / gm
    y = math.sqrt(max(float(h1 @ cov @ h1), 0.0)) / gm
    return x / ARCSEC, y / ARCSEC


# ---------------------------------------------------------------------------------------------
# Chart I-9 / I-10 computed literally (for checking)
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ChartI9:
    sigma_n: np.ndarray
    sigma_alpha: np.ndarray
    tilt: TiltMoments
    sigma_g: np.ndarray
    sigma_N: np.ndarray
    sigma_Z: np.ndarray
    V: np.ndarray
    A: np.ndarray
    B: np.ndarray
    a1: np.ndarray
    a2: np.ndarray

    @property
    def M(self) -> np.ndarray:
        return -np.linalg.solve(self.A, self.B)

    @property
    def b(self) -> np.ndarray:
        return self.a1 + np.linalg.solve(self.A, self.B @ self.a2)


def chart_i9_quantities(params: LevelParams) -> ChartI9:
    """Sigma_Z, V, A, B, a1, a2 as the reconstructed Chart I-9/I-10 defines them.

    Inverts the (3 + 3K) square W = V Sigma_Z V^T; meant for checking, not for large K.
    """
    K, dt = params.K, params.dt
    sn = noise_gram(params.phi_n, dt, K, "phi_n")
    sa = noise_gram(params.phi_alpha, dt, K, "phi_alpha")
    sN = np.kron(np.eye(3), sn + sa)
    tm = tilt_moments(params)
    sg = prior_covariance(params)
    cm = tilt_coefficients(params)
    a1, a2 = prior_mean(params)

    def c_block(a: int, b: int) -> np.ndarray:
        blk = np.empty((K + 1, K + 1))
        blk[0, 0] = tm.c0[a, b]
        blk[0, 1:] = tm.c[a, b]
        blk[1:, 0] = tm.c[b, a]
        blk[1:, 1:] = tm.gram[a, b]
        return blk

    s_theta = np.block([[c_block(0, 0), c_block(0, 1)], [c_block(1, 0), c_block(1, 1)]])
    s_z = block_diag(sg, sN, s_theta)
    nz = 3 + 3 * K + 2 * (K + 1)
    v = np.zeros((3 + 3 * K, nz))
    e_col = 3 + 3 * K  # theta_E(t*), then Theta_E (K), theta_N(t*), Theta_N (K)
    n_col = e_col + K + 1
    v[:3, :3] = np.eye(3)
    v[:3, e_col] = cm[:, 0]
    v[:3, n_col] = cm[:, 1]
    for k in range(3):
        r = slice(3 + k * K, 3 + (k + 1) * K)
        # Chart I-10 prints "Delta t" down the first column for all three axes: each axis's
        # rows carry dt in its own g column (k), as the model requires; the printed g~ (T~1)_k3
        # and -g~ (T~1)_k2 are, with T1 = T^EB as input here, g~ T1[2, k] and -g~ T1[1, k].
        v[r, k] = dt
        v[r, 3 + k * K : 3 + (k + 1) * K] = np.eye(K)
        v[r, e_col + 1 : e_col + 1 + K] = cm[k, 0] * np.eye(K)
        v[r, n_col + 1 : n_col + 1 + K] = cm[k, 1] * np.eye(K)
    w = v @ s_z @ v.T
    p = np.linalg.inv(0.5 * (w + w.T))
    return ChartI9(sn, sa, tm, sg, sN, s_z, v, p[:3, :3], p[:3, 3:], a1, a2)


# ---------------------------------------------------------------------------------------------
# Tables from the lab's NoiseSpec
# ---------------------------------------------------------------------------------------------
def band_covariance(tau: ArrayLike, rms: float, f_lo: float, f_hi: float) -> np.ndarray:
    """rms^2 E[cos(2 pi f tau)] for f uniform on [f_lo, f_hi] (tones uniform in the band)."""
    t = np.abs(np.asarray(tau, dtype=float))
    if f_hi <= f_lo:
        return rms * rms * np.cos(2 * math.pi * f_lo * t)
    x = 2 * math.pi * t
    with np.errstate(invalid="ignore", divide="ignore"):
        v = (np.sin(x * f_hi) - np.sin(x * f_lo)) / (x * (f_hi - f_lo))
    return rms * rms * np.where(t == 0.0, 1.0, v)


def _grid(extent: float, h: float) -> np.ndarray:
    n = int(math.ceil(extent / h - 1e-9))
    return np.arange(n + 1) * h


class TableOptions(TypedDict, total=False):
    """The optional keywords of ``tables_from_noise_spec`` (how finely the tables are made)."""

    vibration_max_lag_s: float | None
    vibration_points_per_cycle: int
    tilt_points_per_period: int


def tables_from_noise_spec(
    noise: NoiseSpec,
    dt: float,
    K: int,
    eps_t: float = 0.0,
    *,
    vibration_max_lag_s: float | None = None,
    vibration_points_per_cycle: int = 20,
    tilt_points_per_period: int = 50,
) -> tuple[CovarianceTable, CovarianceTable, TiltCovarianceTable]:
    """(phi_n, phi_alpha, phi_theta) tables for a record of K samples of dt (Chart I-9).

    * phi_n: the white accelerometer noise, q = (accel_white_micro_g_rt_hz micro-g)^2 per Hz
      (phi_n = q delta(tau): its integral over dt has variance q dt);
    * phi_alpha: floor vibration, tones uniform in ``vibration_band_hz`` with rms
      ``vibration_rms_micro_g`` per axis: rms^2 E_f[cos(2 pi f tau)], tabulated every
      1/(points_per_cycle f_hi) (an integer fraction of dt) up to the record length or
      ``vibration_max_lag_s``, whichever is shorter, zero beyond (it decays as 1/tau and
      its integrals over dt far faster; None keeps the whole length);
    * phi_theta: ``noise.tilt_covariance`` (east, north, cross) every dt/m (m >= 4, at
      least ``tilt_points_per_period`` per wobble period) out to K dt + eps_t + dt.
    """
    extent = K * dt + eps_t + dt
    q = (noise.accel_white_micro_g_rt_hz * MICRO_G) ** 2
    phi_n = CovarianceTable(lags_s=(0.0,), values=(0.0,), white=q, zero_beyond=True)

    rms = noise.vibration_rms_micro_g * MICRO_G
    f_lo, f_hi = noise.vibration_band_hz
    if rms == 0.0:
        phi_alpha = CovarianceTable(lags_s=(0.0,), values=(0.0,), zero_beyond=True)
    else:
        h = dt / math.ceil(dt * vibration_points_per_cycle * f_hi)
        reach = extent if vibration_max_lag_s is None else min(extent, vibration_max_lag_s)
        lags = _grid(reach, h)
        phi_alpha = CovarianceTable(
            lags_s=tuple(lags.tolist()),
            values=tuple(band_covariance(lags, rms, f_lo, f_hi).tolist()),
            zero_beyond=reach < extent,
        )

    m = max(4, math.ceil(dt * tilt_points_per_period / noise.wobble_period_s))
    lags = _grid(extent, dt / m)
    ee, nn, en = noise.tilt_covariance(lags)
    phi_theta = TiltCovarianceTable(
        lags_s=tuple(lags.tolist()),
        east=tuple(np.asarray(ee).tolist()),
        north=tuple(np.asarray(nn).tolist()),
        cross=tuple(np.asarray(en).tolist()),
    )
    return phi_n, phi_alpha, phi_theta


def level_params_from_noise_spec(
    noise: NoiseSpec,
    dt: float,
    K: int,
    *,
    g_tilde: float,
    sigma_g: float,
    T1: ArrayLike,
    sigma_theta: float,
    eps_t: float = 0.0,
    **table_options: Unpack[TableOptions],
) -> LevelParams:
    """``LevelParams`` whose three tables come from ``tables_from_noise_spec``."""
    phi_n, phi_alpha, phi_theta = tables_from_noise_spec(noise, dt, K, eps_t, **table_options)
    return LevelParams(
        dt=dt,
        K=K,
        g_tilde=g_tilde,
        sigma_g=sigma_g,
        T1=tuple(tuple(float(x) for x in row) for row in np.asarray(T1, dtype=float)),
        sigma_theta=sigma_theta,
        phi_n=phi_n,
        phi_alpha=phi_alpha,
        phi_theta=phi_theta,
        eps_t=eps_t,
    )
