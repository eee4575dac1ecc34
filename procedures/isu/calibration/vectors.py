"""3-vector arithmetic of the calibration's inner loops, without numpy's per-call cost.

The calibration program (procedures, which see drivers and the clock, never the
simulation) keeps its own: the cross products and norms of its models, bit for bit the
ones numpy computes.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt


def cross3(a: npt.ArrayLike, b: npt.ArrayLike) -> np.ndarray:
    """a x b of two 3-vectors: numpy.cross's arithmetic (bit for bit) without its axis
    handling, which costs about 20 us a call in the calibration's inner loops."""
    a0, a1, a2 = np.asarray(a, dtype=float).tolist()
    b0, b1, b2 = np.asarray(b, dtype=float).tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def norm3(v: np.ndarray) -> float:
    """Euclidean length of a vector as numpy.linalg.norm computes it (sqrt of v.v)."""
    return math.sqrt(float(v.dot(v)))
