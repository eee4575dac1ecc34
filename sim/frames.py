"""Frame algebra of report 000: T^XY_ij = X_i . Y_j, products compose left to right.

Chart I-4 writes every gimbal transform in one form (``gimbal``); increasing the angle turns
the inner frame about its own axis 1 in the positive sense.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt


def gimbal(p: float | np.ndarray) -> np.ndarray:
    """Chart I-4 gimbal transform [[0,1,0],[cos p,0,-sin p],[-sin p,0,-cos p]]; p scalar or (N,)."""
    p = np.asarray(p, dtype=float)
    c, s = np.cos(p), np.sin(p)
    m = np.zeros(p.shape + (3, 3))
    m[..., 0, 1] = 1.0
    m[..., 1, 0] = c
    m[..., 1, 2] = -s
    m[..., 2, 0] = -s
    m[..., 2, 2] = -c
    return m


def gimbal_at(p: float) -> np.ndarray:
    """``gimbal`` of one angle, (3, 3): its cosine and sine as numpy computes them for an
    array, the matrix built at once (a twentieth of the calls, issue 17)."""
    c, s = float(np.cos(p)), float(np.sin(p))
    return np.array([[0.0, 1.0, 0.0], [c, 0.0, -s], [-s, 0.0, -c]])


def transform_of_rotated_at(v: npt.ArrayLike) -> np.ndarray:
    """``transform_of_rotated`` of one rotation vector, (3, 3): ``rotation``'s arithmetic
    term by term (its norm, the branch its ``where`` takes, the same products in the same
    order) without the array machinery around it (issue 17: a table's frames at one
    instant, 465 a day; tests/test_fast_paths.py holds it to the array path)."""
    x, y, w = (float(e) for e in np.asarray(v, dtype=float))
    th = float(np.linalg.norm(np.array([[x, y, w]]), axis=1)[0])
    if th < 1e-8:
        a, b = 1.0 - th * th / 6.0, 0.5 - th * th / 24.0
    else:
        a, b = float(np.sin(th)) / th, (1.0 - float(np.cos(th))) / (th * th)
    k = np.array([[0.0, -w, y], [w, 0.0, -x], [-y, x, 0.0]])
    return (np.eye(3) + a * k + b * (k @ k)).T


def rotation(v: npt.ArrayLike) -> np.ndarray:
    """Rotation matrix turning vectors by rotation vector v (Rodrigues); v (3,) or (N, 3)."""
    v = np.asarray(v, dtype=float)
    single = v.ndim == 1
    v = np.atleast_2d(v)
    th = np.linalg.norm(v, axis=1)
    small = th < 1e-8
    th_safe = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th**2 / 6.0, np.sin(th) / th_safe)
    b = np.where(small, 0.5 - th**2 / 24.0, (1.0 - np.cos(th)) / th_safe**2)
    k = skew(v)
    eye = np.broadcast_to(np.eye(3), k.shape)
    r = eye + a[:, None, None] * k + b[:, None, None] * (k @ k)
    return r[0] if single else r


def skew(v: npt.ArrayLike) -> np.ndarray:
    """Cross-product matrix [v x] for v of shape (..., 3)."""
    v = np.asarray(v, dtype=float)
    k = np.zeros(v.shape[:-1] + (3, 3))
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    k[..., 0, 1], k[..., 0, 2] = -w, y
    k[..., 1, 0], k[..., 1, 2] = w, -x
    k[..., 2, 0], k[..., 2, 1] = -y, x
    return k


def transform_of_rotated(v: npt.ArrayLike) -> np.ndarray:
    """T^XY of a frame X obtained by turning frame Y by rotation vector v (Y components)."""
    r = rotation(v)
    return np.swapaxes(r, -1, -2)

