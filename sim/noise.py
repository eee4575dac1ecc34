"""Seeded noise processes held as piecewise-linear functions on fixed knot grids.

Each process is generated lazily, block by block, from a stream named after it, so its
value at a time does not depend on the order of queries. Between knots the process is
linear; its value and its running integral are therefore exact and O(1) per query.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import overload

import numpy as np

from sim.rng import stream

BLOCK = 4096  # knots generated at a time by a sequential (Gauss-Markov) process
PATH_BLOCK = 1024  # knots of one Brownian-bridge block of a random walk
TOTALS_CHUNK = 64  # random-walk block totals drawn at a time


class KnotProcess:
    """A process known at knots ``k * h`` and linear in between.

    ``step(rng, x_prev, n)`` returns the next ``n`` knot values given the last one.
    """

    def __init__(
        self,
        h: float,
        seed: int,
        names: tuple[str | int, ...],
        first: Callable[[np.random.Generator], float],
        step: Callable[[np.random.Generator, float, int], np.ndarray],
    ) -> None:
        self.h = float(h)
        self._seed = seed
        self._names = names
        self._step = step
        x0 = first(stream(seed, *names, "first"))
        self._x = np.array([x0], dtype=float)
        self._cum = np.array([0.0])  # integral from 0 to knot k
        self._blocks = 0

    def _ensure(self, k_max: int) -> None:
        while self._x.size <= k_max + 1:
            rng = stream(self._seed, *self._names, self._blocks)
            new = self._step(rng, float(self._x[-1]), BLOCK)
            xs = np.concatenate(([self._x[-1]], new))
            seg = 0.5 * self.h * (xs[1:] + xs[:-1])
            self._cum = np.concatenate((self._cum, self._cum[-1] + np.cumsum(seg)))
            self._x = np.concatenate((self._x, new))
            self._blocks += 1

    def _locate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u = np.maximum(t, 0.0) / self.h
        k = np.floor(u).astype(np.int64)
        self._ensure(int(k.max()) if k.size else 0)
        return k, u - k

    @overload
    def value(self, t: float) -> float: ...
    @overload
    def value(self, t: np.ndarray) -> np.ndarray: ...
    def value(self, t: float | np.ndarray) -> float | np.ndarray:
        """Process value at time(s) t (seconds)."""
        ta = np.asarray(t, dtype=float)
        k, f = self._locate(np.atleast_1d(ta))
        v = self._x[k] * (1.0 - f) + self._x[k + 1] * f
        return v.reshape(ta.shape) if ta.ndim else float(v[0])

    def value_and_slope(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Value and time derivative (piecewise constant) at an array of times."""
        k, f = self._locate(np.atleast_1d(np.asarray(t, dtype=float)))
        x0, x1 = self._x[k], self._x[k + 1]
        return x0 + (x1 - x0) * f, (x1 - x0) / self.h

    def _locate_one(self, t: float) -> tuple[int, float]:
        """``_locate`` of one time, in Python numbers: the same operations, the same bits."""
        u = max(t, 0.0) / self.h
        k = math.floor(u)
        self._ensure(k)
        return k, u - k

    def value_and_slope_at(self, t: float) -> tuple[float, float]:
        """``value_and_slope`` at one time, in Python floats: the same operations in the
        same order, so the same bits (issue 17)."""
        k, f = self._locate_one(t)
        x0, x1 = float(self._x[k]), float(self._x[k + 1])
        return float(x0 + (x1 - x0) * f), float((x1 - x0) / self.h)

    @overload
    def integral(self, t: float) -> float: ...
    @overload
    def integral(self, t: np.ndarray) -> np.ndarray: ...
    def integral(self, t: float | np.ndarray) -> float | np.ndarray:
        """Integral of the process from 0 to time(s) t (one time: in Python floats, the same
        operations in the same order as the array's, so the same bits; issue 17)."""
        if isinstance(t, float):  # a Python float or a numpy float64 scalar
            kk, ff = self._locate_one(t)
            x0s, x1s = float(self._x[kk]), float(self._x[kk + 1])
            return float(float(self._cum[kk]) + self.h * ff * (x0s + 0.5 * ff * (x1s - x0s)))
        ta = np.asarray(t, dtype=float)
        k, f = self._locate(np.atleast_1d(ta))
        x0 = self._x[k]
        x1 = self._x[k + 1]
        v = self._cum[k] + self.h * f * (x0 + 0.5 * f * (x1 - x0))
        return v.reshape(ta.shape) if ta.ndim else float(v[0])


def _ar1(a: float, x: float, w: np.ndarray) -> np.ndarray:
    """x_i = a x_{i-1} + w_i from x_0 = x (a stable first-order filter: finite for every
    0 <= a <= 1 and every finite w).

    The same operations in the same order as scipy.signal.lfilter([1], [1, -a], w,
    zi=[a x]), so the same bits; a plain loop (about 0.25 ms per 4096-knot block) because
    importing scipy.signal costs about 0.3 s of every command's start."""
    out = [0.0] * len(w)
    y = a * x
    for i, wi in enumerate(w.tolist()):
        y += wi
        out[i] = y
        y *= a
    return np.array(out)


class RandomWalk:
    """Wiener process W(0)=0 with variance ``q * t`` (q in units^2/s): integrated white noise.

    Knots every ``h`` s, linear in between. Block totals are drawn first and each block's path
    is a Brownian bridge between them, drawn only when a time inside the block is asked for:
    the value at any time costs O(1) however far it lies, and never depends on query order.
    """

    def __init__(self, h: float, q: float, seed: int, names: tuple[str | int, ...]) -> None:
        self.h = float(h)
        self._sd = math.sqrt(max(q, 0.0) * h)
        self._seed = seed
        self._names = names
        self._starts = np.zeros(1)  # W at the start of each block
        self._paths: dict[int, np.ndarray] = {}

    def _start(self, b: int) -> float:
        while self._starts.size <= b:
            c = (self._starts.size - 1) // TOTALS_CHUNK  # next chunk of block totals
            z = stream(self._seed, *self._names, "totals", c).standard_normal(TOTALS_CHUNK)
            tot = z * self._sd * math.sqrt(PATH_BLOCK)
            self._starts = np.concatenate((self._starts, self._starts[-1] + np.cumsum(tot)))
        return float(self._starts[b])

    def _path(self, b: int) -> np.ndarray:
        """W at knots b*PATH_BLOCK .. (b+1)*PATH_BLOCK inclusive."""
        p = self._paths.get(b)
        if p is None:
            w0, w1 = self._start(b), self._start(b + 1)
            z = stream(self._seed, *self._names, "path", b).standard_normal(PATH_BLOCK)
            x = np.concatenate(([0.0], np.cumsum(z * self._sd)))
            x -= np.arange(PATH_BLOCK + 1) / PATH_BLOCK * (x[-1] - (w1 - w0))
            p = w0 + x
            self._paths[b] = p
        return p

    def _knots(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        u = np.maximum(t, 0.0) / self.h
        k = np.floor(u).astype(np.int64)
        x0 = np.empty(k.size)
        x1 = np.empty(k.size)
        for i, kk in enumerate(k):
            b, r = divmod(int(kk), PATH_BLOCK)
            p = self._path(b)
            x0[i], x1[i] = p[r], p[r + 1]
        return x0, x1, u - k

    @overload
    def value(self, t: float) -> float: ...
    @overload
    def value(self, t: np.ndarray) -> np.ndarray: ...
    def value(self, t: float | np.ndarray) -> float | np.ndarray:
        """Value at time(s) t (seconds); one time in Python floats, as ``integral``."""
        if isinstance(t, float):
            u = max(t, 0.0) / self.h
            b, r = divmod(math.floor(u), PATH_BLOCK)
            p = self._path(b)
            x0s, x1s = float(p[r]), float(p[r + 1])
            return float(x0s + (x1s - x0s) * (u - (b * PATH_BLOCK + r)))
        ta = np.asarray(t, dtype=float)
        x0, x1, f = self._knots(np.atleast_1d(ta))
        v = x0 + (x1 - x0) * f
        return v.reshape(ta.shape) if ta.ndim else float(v[0])



def random_walk(h: float, q: float, seed: int, *names: str | int) -> RandomWalk:
    """Wiener process W(0)=0, variance ``q * t`` (q in units^2/s): integrated white noise."""
    return RandomWalk(h, q, seed, names)


def gauss_markov(h: float, sigma: float, tau: float, seed: int, *names: str | int) -> KnotProcess:
    """Stationary first-order Gauss-Markov process: covariance sigma^2 exp(-|dt|/tau).

    Exact discretisation at the knots, for any tau > 0 against the step h:
    phi = exp(-h/tau), innovation variance sigma^2 (1 - phi^2) (no Euler step to go
    unstable when tau nears h). Between knots the process is linear.
    """
    a = math.exp(-h / tau)
    b = sigma * math.sqrt(-math.expm1(-2.0 * h / tau))  # sigma sqrt(1 - a^2), exact for small h/tau

    def step(rng: np.random.Generator, x: float, n: int) -> np.ndarray:
        return _ar1(a, x, rng.standard_normal(n) * b)

    return KnotProcess(h, seed, names, lambda rng: float(rng.standard_normal() * sigma), step)


class Multitone:
    """Band-limited stationary noise as a sum of sinusoids with seeded frequencies and phases.

    Covariance: sum_k (A_k^2 / 2) cos(w_k tau). Value and running integral are closed form.
    """

    def __init__(self, rms: float, f_lo: float, f_hi: float, n: int, seed: int,
                 *names: str | int) -> None:
        rng = stream(seed, *names)
        self.w = 2.0 * math.pi * rng.uniform(f_lo, f_hi, n)
        self.amp = np.full(n, rms * math.sqrt(2.0 / n))
        self.psi = rng.uniform(0.0, 2.0 * math.pi, n)
        self._c = self.amp / self.w  # the integral's amplitudes, and its value at 0
        self._at_zero = float(np.sin(self.psi) @ self._c)

    @overload
    def value(self, t: float) -> float: ...
    @overload
    def value(self, t: np.ndarray) -> np.ndarray: ...
    def value(self, t: float | np.ndarray) -> float | np.ndarray:
        """Value at time(s) t (seconds)."""
        ta = np.asarray(t, dtype=float)
        v = np.cos(np.multiply.outer(ta, self.w) + self.psi) @ self.amp
        return v if ta.ndim else float(v)

    def value_and_rate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Value and time derivative at an array of times, sharing the phases."""
        ph = np.multiply.outer(np.atleast_1d(np.asarray(t, dtype=float)), self.w) + self.psi
        return np.cos(ph) @ self.amp, -np.sin(ph) @ (self.amp * self.w)

    @overload
    def integral(self, t: float) -> float: ...
    @overload
    def integral(self, t: np.ndarray) -> np.ndarray: ...
    def integral(self, t: float | np.ndarray) -> float | np.ndarray:
        """Integral from 0 to t."""
        ta = np.asarray(t, dtype=float)
        v = np.sin(np.multiply.outer(ta, self.w) + self.psi) @ self._c - self._at_zero
        return v if ta.ndim else float(v)

    def integral_each(self, t: np.ndarray) -> np.ndarray:
        """:meth:`integral` at each of the times t, each with the bits it has asked for alone
        (a stack of one-row products: BLAS sums the rows of one big product otherwise)."""
        s = np.sin(np.multiply.outer(np.asarray(t, dtype=float), self.w) + self.psi)
        return np.matmul(s[:, None, :], self._c)[:, 0] - self._at_zero

    def covariance(self, tau: float | np.ndarray) -> np.ndarray:
        """Covariance at lag(s) tau."""
        ta = np.asarray(tau, dtype=float)
        return np.cos(np.multiply.outer(ta, self.w)) @ (0.5 * self.amp**2)


class Multitones:
    """Several multitones of as many tones each (the axes of one noise), asked at one
    instant together: one stacked evaluation whose elementwise operations are each
    multitone's own and whose sums are one dot product per multitone, as each one's own
    one-instant product (numpy's matmul of a row and a column), so every value has the
    bits that multitone gives alone, in a fraction of the numpy calls (issue 17)."""

    def __init__(self, tones: list[Multitone]) -> None:
        self._w = np.stack([m.w for m in tones])
        self._psi = np.stack([m.psi for m in tones])
        self._amp = np.stack([m.amp for m in tones])[:, :, None]
        self._amp_w = np.stack([m.amp * m.w for m in tones])[:, :, None]
        self._c = np.stack([m._c for m in tones])[:, :, None]
        self._at_zero = np.array([m._at_zero for m in tones])

    def _dot(self, rows: np.ndarray, columns: np.ndarray) -> np.ndarray:
        return np.matmul(rows[:, None, :], columns)[:, 0, 0]

    def value_and_rate_at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Each multitone's ``value_and_rate`` at the time t."""
        ph = t * self._w + self._psi
        return self._dot(np.cos(ph), self._amp), self._dot(-np.sin(ph), self._amp_w)

    def integral_at(self, t: float) -> np.ndarray:
        """Each multitone's ``integral`` at the time t."""
        return self._dot(np.sin(t * self._w + self._psi), self._c) - self._at_zero
