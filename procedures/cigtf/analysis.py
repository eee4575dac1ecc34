"""Data analysis of the four-orientation test (report 001, eqs. 15-25)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class OrientationValues:
    """Mean, sample variance and variance of the mean of one orientation (eqs. 15-17)."""

    mean: float
    variance: float
    variance_of_mean: float
    count: int


@dataclass(frozen=True)
class RunValues:
    """Gyrocompassing error of one run and its standard error, arcsec (eqs. 18-19)."""

    theta: float
    sigma: float
    orientations: tuple[OrientationValues, ...]

    @property
    def noise_dof(self) -> int:
        """Degrees of freedom of the within-orientation variances of this run."""
        return sum(o.count - 1 for o in self.orientations)


@dataclass(frozen=True)
class PhaseValues:
    """Phase error, its standard error, RMS run error and instability (eqs. 20-25)."""

    theta: float
    sigma: float
    s: float
    instability: float
    n: int
    noise_dof: int


def orientation_values(samples: Sequence[float]) -> OrientationValues:
    """Eqs. 15-17 for the ten-second averaged currents of one orientation."""
    x = np.asarray(samples, dtype=float)
    if x.ndim != 1 or x.size < 2:
        raise ValueError("an orientation needs at least two current samples")
    var = float(x.var(ddof=1))
    return OrientationValues(float(x.mean()), var, var / x.size, int(x.size))


def run_values(samples: Sequence[Sequence[float]], gsf: float) -> RunValues:
    """Eqs. 18-19 from the samples of orientations 1, 2, 3, 4 (in that order)."""
    if len(samples) != 4:
        raise ValueError("a run has exactly four orientations")
    o = tuple(orientation_values(s) for s in samples)
    theta = gsf * (o[0].mean + o[2].mean - o[1].mean - o[3].mean)
    sigma = abs(gsf) * math.sqrt(sum(v.variance_of_mean for v in o))
    return RunValues(theta, sigma, o)


def phase_values(runs: Sequence[RunValues]) -> PhaseValues:
    """Eqs. 20-23 and the instability of eqs. 24/25 (sample SD of the run thetas)."""
    n = len(runs)
    if n < 2:
        raise ValueError("a phase needs at least two runs")
    thetas = np.array([r.theta for r in runs])
    sig2 = np.array([r.sigma**2 for r in runs])
    sigma = math.sqrt(float(sig2.sum())) / n
    return PhaseValues(
        theta=float(thetas.mean()),
        sigma=sigma,
        s=math.sqrt(n) * sigma,
        instability=float(thetas.std(ddof=1)),
        n=n,
        noise_dof=sum(r.noise_dof for r in runs),
    )
