"""Medians as numpy.median gives them, without its import of numpy.ma.

numpy.median checks its partition for NaN through ``np.ma.isMaskedArray``, which imports
numpy.ma (8 ms of every calibration day, at its survey's first median; issue 17). This is
its arithmetic on plain arrays: the same partition, the mean of the same middle slice and
NaN where the slice's axis holds one; tests/test_fast_paths.py holds it to numpy.median.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt


def median(a: npt.ArrayLike, axis: int | None = None) -> Any:
    """numpy.median(a, axis) of a float array (flattened when ``axis`` is None)."""
    x = np.asarray(a, dtype=float)
    if axis is None:
        x, axis = x.ravel(), 0
    n = x.shape[axis]
    if n == 0:  # numpy's warning and NaN
        return np.median(x, axis=axis)
    half = n // 2
    part = np.partition(x, [half - 1, half, -1] if n % 2 == 0 else [(n - 1) // 2, -1],
                        axis=axis)
    index: list[slice] = [slice(None)] * part.ndim
    index[axis] = slice(half - 1, half + 1) if n % 2 == 0 else slice(half, half + 1)
    out = np.mean(part[tuple(index)], axis=axis)
    nan = np.isnan(part.take(-1, axis=axis))  # NaN sorts last: any on the axis is there
    if not nan.any():
        return out
    if np.ndim(out) == 0:
        return np.float64(np.nan)
    out[nan] = np.nan
    return out
