"""Significance tests of report 001 section 5.4 at the actual degrees of freedom.

The points are scipy.special's (stdtrit, fdtri): the very functions scipy.stats.t.ppf and
f.ppf return, so the same bits, without importing scipy.stats (about 0.25 s at start).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from procedures.cigtf.analysis import PhaseValues
from procedures.quantiles import f_quantile, t_quantile

ALPHA = 0.05


@dataclass(frozen=True)
class TestOutcome:
    """A statistic, its threshold at ALPHA and whether it is significant."""

    statistic: float
    threshold: float
    dof: tuple[int, ...]

    @property
    def significant(self) -> bool:
        """True when the statistic reaches the threshold."""
        return self.statistic >= self.threshold


def t_threshold(dof: int, alpha: float = ALPHA) -> float:
    """Two-sided Student t point; 1.96 for the report's large dof."""
    return t_quantile(1.0 - alpha / 2.0, dof)


def f_threshold(dfn: int, dfd: int, alpha: float = ALPHA) -> float:
    """Upper F point: 1.53 (24, 900), 1.91 (9, 360), 2.30 (9, 24) in the report."""
    return f_quantile(1.0 - alpha, dfn, dfd)


def noise_f_test(phase: PhaseValues, alpha: float = ALPHA) -> TestOutcome:
    """Instability squared over s_j squared (5.4.2 for j=1, 5.4.3 for j=2)."""
    dof = (phase.n - 1, phase.noise_dof)
    ratio = phase.instability**2 / phase.s**2 if phase.s > 0 else math.inf
    return TestOutcome(ratio, f_threshold(*dof, alpha), dof)


def shutdown_f_test(
    operating: PhaseValues, shutdown: PhaseValues, alpha: float = ALPHA
) -> TestOutcome:
    """Delta squared over delta squared (5.4.4)."""
    dof = (shutdown.n - 1, operating.n - 1)
    d2 = operating.instability**2
    ratio = shutdown.instability**2 / d2 if d2 > 0 else math.inf
    return TestOutcome(ratio, f_threshold(*dof, alpha), dof)


def phase_standard_error(phase: PhaseValues, corrected: bool) -> tuple[float, int]:
    """Eq. 21 with noise dof, or instability/sqrt(n) with n-1 dof (5.4.2 correction)."""
    if corrected:
        return phase.instability / math.sqrt(phase.n), phase.n - 1
    return phase.sigma, phase.noise_dof


def mean_t_test(phase: PhaseValues, corrected: bool, alpha: float = ALPHA) -> TestOutcome:
    """|theta_j / sigma_theta_j| against Student t (5.4.1, corrected per 5.4.2)."""
    se, dof = phase_standard_error(phase, corrected)
    stat = abs(phase.theta) / se if se > 0 else math.inf
    return TestOutcome(stat, t_threshold(dof, alpha), (dof,))


@dataclass(frozen=True)
class PhaseVerdict:
    """The noise F test, the standard error used and the t test of one phase."""

    phase: PhaseValues
    noise_test: TestOutcome
    standard_error: float
    mean_test: TestOutcome


def judge_phase(phase: PhaseValues, alpha: float = ALPHA) -> PhaseVerdict:
    """F test first; a significant one switches the phase to instability/sqrt(n)."""
    f = noise_f_test(phase, alpha)
    se, _ = phase_standard_error(phase, f.significant)
    return PhaseVerdict(phase, f, se, mean_t_test(phase, f.significant, alpha))


@dataclass(frozen=True)
class TestReport:
    """Both phases judged and the shutdown-versus-operating F test."""

    operating: PhaseVerdict
    shutdown: PhaseVerdict
    shutdown_test: TestOutcome


def judge(operating: PhaseValues, shutdown: PhaseValues, alpha: float = ALPHA) -> TestReport:
    """All of section 5.4; the shutdown phase takes the 5.4.2 correction by analogy."""
    return TestReport(
        judge_phase(operating, alpha),
        judge_phase(shutdown, alpha),
        shutdown_f_test(operating, shutdown, alpha),
    )
