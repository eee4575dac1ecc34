"""Spin-axis direction from the pickoffs' direction cosines (report 004, "Line edge error
estimation", eqs. (1)-(3) of the pattern-analysis section).

Each pickoff i (unit vector p_i in the case frame, rows of the pickoff matrix P) measures
alpha_i = cos(th_i) = p_i . s. Nominally P = I (orthogonal pickoffs) and alpha_i are the
direction cosines of s; in general the pickoffs are slightly non-orthogonal (mirrors at
89 deg 56 min 5 sec) and the solution goes through P^-1 (equivalently P' G^-1 with the
Gram matrix G = P P').

Modes

* three-pickoff: s = P^-1 alpha, then ordinary normalisation s / |s|;
* two-pickoff (pair i, j, third k): s = s0 + t n, s0 = [p_i p_j] G2^-1 (alpha_i, alpha_j)
  the part in the pair's plane, n = p_i x p_j normalised and turned toward p_k, and
  t = sign * sqrt(1 - |s0|^2). For P = I this is the orthogonality identity
  alpha_k = +-sqrt(1 - alpha_i^2 - alpha_j^2); ``sign`` is the third cosine's sign (from
  past information; for non-orthogonal pickoffs, strictly the sign along n, which differs
  from the third cosine's only when that cosine is within the misalignment of zero, where
  the two-pickoff mode is never used). The pair nearest the equator (smallest |alpha|)
  is the best choice (eq. (2) has the largest denominator);
* mixed: three-pickoff when all three view the pattern, else two-pickoff with the two
  that do (the report's preferred strategy).

Error propagation (orthogonal pickoffs, independent cosine errors of variance v_i):

* two-pickoff: alpha_k = sign sqrt(1 - a^2 - b^2), d alpha_k = -(a da + b db)/alpha_k, so
  E|dS|^2 = v_a + v_b + (a^2 v_a + b^2 v_b)/alpha_k^2
          = ((1 - b^2) v_a + (1 - a^2) v_b) / (1 - a^2 - b^2)                    (2)
* three-pickoff normalised: dS = (I - s s') d alpha, so
  E|dS|^2 = sum_i (1 - alpha_i^2) v_i                                            (3)

The general (non-orthogonal) Jacobians: two-pickoff from differentiating
p_i . s = alpha_i, p_j . s = alpha_j, s . s = 1, i.e. dS = M^-1 (da_i, da_j, 0) with M
rows (p_i, p_j, s); three-pickoff dS = (I - s s') P^-1 d alpha (|P^-1 alpha| = 1 at truth).

All functions take cosines with shape (..., 3) and broadcast over the leading axes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "orthogonal_pickoffs",
    "pickoffs_from_mirrors",
    "spin_axis_three",
    "spin_axis_two",
    "nearest_equator_pair",
    "spin_axis_mixed",
    "variance_two",
    "variance_three",
    "jacobian_two",
    "jacobian_three",
    "propagated_variance",
]


def orthogonal_pickoffs() -> np.ndarray:
    return np.eye(3)


def pickoffs_from_mirrors(mirror_angle_deg: float) -> np.ndarray:
    """p1 = c1, p2 in the c1-c2 plane at the mirror angle from p1, p3 normal to both."""
    a = np.radians(mirror_angle_deg)
    return np.array([[1.0, 0.0, 0.0], [np.cos(a), np.sin(a), 0.0], [0.0, 0.0, 1.0]])


def _p(pickoffs: ArrayLike | None) -> np.ndarray:
    return orthogonal_pickoffs() if pickoffs is None else np.asarray(pickoffs, dtype=float)


def spin_axis_three(cosines: ArrayLike, pickoffs: ArrayLike | None = None) -> np.ndarray:
    """Three-pickoff mode with ordinary normalisation: s = P^-1 alpha / |P^-1 alpha|."""
    a = np.asarray(cosines, dtype=float)
    v = a @ np.linalg.inv(_p(pickoffs)).T
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _third(pair: ArrayLike) -> np.ndarray:
    pair = np.asarray(pair)
    return 3 - pair[..., 0] - pair[..., 1]


def spin_axis_two(cosines: ArrayLike, pair: ArrayLike, sign: ArrayLike,
                  pickoffs: ArrayLike | None = None) -> np.ndarray:
    """Two-pickoff mode with pickoffs ``pair`` = (i, j) (0-based; shape (2,) or (..., 2)).

    The third component comes from the orthogonality identity (general geometry: the
    unit-length condition), ``sign`` (+1/-1, broadcast) being the sign of the third
    pickoff's cosine. Cosines of the third pickoff are ignored (may be NaN).
    """
    p = _p(pickoffs)
    a = np.asarray(cosines, dtype=float)
    pair = np.broadcast_to(np.asarray(pair), a.shape[:-1] + (2,))
    i, j, k = pair[..., 0], pair[..., 1], _third(pair)
    pi, pj, pk = p[i], p[j], p[k]                       # (..., 3)
    ai = np.take_along_axis(a, i[..., None], -1)[..., 0]
    aj = np.take_along_axis(a, j[..., None], -1)[..., 0]
    gii = (pi * pi).sum(-1)
    gjj = (pj * pj).sum(-1)
    gij = (pi * pj).sum(-1)
    det = gii * gjj - gij * gij
    ci = (gjj * ai - gij * aj) / det
    cj = (gii * aj - gij * ai) / det
    s0 = ci[..., None] * pi + cj[..., None] * pj
    n = np.cross(pi, pj)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    n = n * np.where((n * pk).sum(-1) < 0.0, -1.0, 1.0)[..., None]
    t = np.sqrt(np.clip(1.0 - (s0 * s0).sum(-1), 0.0, None))
    return s0 + (np.where(np.asarray(sign) < 0, -1.0, 1.0) * t)[..., None] * n


def nearest_equator_pair(cosines: ArrayLike, viewing: ArrayLike | None = None) -> np.ndarray:
    """The two pickoffs with the smallest |cosine| (among those viewing, if given)."""
    a = np.abs(np.asarray(cosines, dtype=float))
    if viewing is not None:
        a = np.where(viewing, a, np.inf)
    order = np.argsort(a, axis=-1, kind="stable")
    return np.sort(order[..., :2], axis=-1)


def spin_axis_mixed(cosines: ArrayLike, viewing: ArrayLike, signs: ArrayLike,
                    pickoffs: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Mixed strategy: (s, mode), mode 3 where all three view, 2 where two do, 0 where fewer.

    ``viewing`` (bool, (..., 3)) says which pickoffs see the pattern; ``signs`` ((..., 3)
    or scalar) are the cosines' signs from past information, of which the one belonging to
    the pickoff left out of a two-pickoff solution is used. Cosines of pickoffs not viewing
    are ignored (may be NaN); rows with mode 0 come back NaN.
    """
    a = np.asarray(cosines, dtype=float)
    v = np.broadcast_to(np.asarray(viewing, dtype=bool), a.shape)
    nv = v.sum(-1)
    pair = nearest_equator_pair(a, v)
    k = _third(pair)
    sg = np.broadcast_to(np.asarray(signs, dtype=float), a.shape)
    sign = np.take_along_axis(sg, k[..., None], -1)[..., 0]
    a_fill = np.where(v, a, 0.0)
    s2 = spin_axis_two(a_fill, pair, sign, pickoffs)
    s3 = spin_axis_three(a_fill, pickoffs)
    s = np.where((nv == 3)[..., None], s3, s2)
    s = np.where((nv >= 2)[..., None], s, np.nan)
    return s, np.where(nv >= 3, 3, np.where(nv == 2, 2, 0))


def variance_two(alpha: ArrayLike, beta: ArrayLike, var_alpha: float | np.ndarray,
                 var_beta: float | np.ndarray) -> np.ndarray:
    """Eq. (2): E|dS|^2 of the two-pickoff mode (orthogonal pickoffs)."""
    a2, b2 = np.square(alpha), np.square(beta)
    return ((1.0 - b2) * var_alpha + (1.0 - a2) * var_beta) / (1.0 - a2 - b2)


def variance_three(cosines: ArrayLike, variances: ArrayLike) -> np.ndarray:
    """Eq. (3): E|dS|^2 of the normalised three-pickoff mode (orthogonal pickoffs)."""
    a = np.asarray(cosines, dtype=float)
    return ((1.0 - a * a) * np.asarray(variances, dtype=float)).sum(-1)


def jacobian_two(s: ArrayLike, pair: Sequence[int] | np.ndarray,
                 pickoffs: ArrayLike | None = None) -> np.ndarray:
    """dS/d(alpha_i, alpha_j) (3 x 2) of the two-pickoff mode at the true axis s."""
    p = _p(pickoffs)
    i, j = int(pair[0]), int(pair[1])
    m = np.stack([p[i], p[j], np.asarray(s, dtype=float)])
    return np.linalg.inv(m)[:, :2]


def jacobian_three(s: ArrayLike, pickoffs: ArrayLike | None = None) -> np.ndarray:
    """dS/d alpha (3 x 3) of the normalised three-pickoff mode at the true axis s."""
    s = np.asarray(s, dtype=float)
    return (np.eye(3) - np.outer(s, s)) @ np.linalg.inv(_p(pickoffs))


def propagated_variance(jacobian: ArrayLike, variances: ArrayLike) -> float:
    """E|dS|^2 = trace(J diag(v) J') for independent cosine errors."""
    j = np.asarray(jacobian, dtype=float)
    return float(((j * j) * np.asarray(variances, dtype=float)).sum())
