"""Frame algebra of report 000: T^XY_ij = X_i . Y_j, products compose left to right.

Chart I-4 writes every gimbal transform in one form (``gimbal``); increasing the angle turns
the inner frame about its own axis 1 in the positive sense.
"""

from __future__ import annotations

import numpy as np


def gimbal(p) -> np.ndarray:
    """Chart I-4 gimbal transform [[0,1,0],[cos p,0,-sin p],[-sin p,0,-cos p]]; p scalar or (N,)."""
    p = np.asarray(p, dtype=float)
    c, s = np.cos(p), np.sin(p)
    z, o = np.zeros_like(p), np.ones_like(p)
    m = np.stack([np.stack([z, o, z], -1), np.stack([c, z, -s], -1), np.stack([-s, z, -c], -1)], -2)
    return m


def rotation(v) -> np.ndarray:
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


def skew(v) -> np.ndarray:
    """Cross-product matrix [v x] for v of shape (..., 3)."""
    v = np.asarray(v, dtype=float)
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack(
        [np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2
    )


def transform_of_rotated(v) -> np.ndarray:
    """T^XY of a frame X obtained by turning frame Y by rotation vector v (Y components)."""
    r = rotation(v)
    return np.swapaxes(r, -1, -2)
