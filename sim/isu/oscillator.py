"""Master oscillator with two countdown outputs: S1^T to the counters, S2^T to the IEU."""

from __future__ import annotations

import math

from sim.isu.params import OscillatorParams
from sim.rng import stream

DAY = 86400.0


class MasterOscillator:
    """Oscillator phase is closed form: f(t) = f_nom (1 + e0 + d t)."""

    def __init__(self, p: OscillatorParams, seed: int) -> None:
        self.p = p
        self.f = p.nominal_hz
        self.e0 = p.frequency_error
        self.d = p.drift_per_day / DAY
        self.phase0 = float(stream(seed, "oscillator").uniform())

    @property
    def s1_nominal(self) -> float:
        """Nominal S1^T, seconds per counter timing pulse."""
        return self.p.s1_divider / self.p.nominal_hz

    @property
    def s2_nominal(self) -> float:
        return self.p.s2_divider / self.p.nominal_hz

    def phase(self, t: float) -> float:
        return self.f * (t * (1.0 + self.e0) + 0.5 * self.d * t * t) + self.phase0

    def time_of_phase(self, ph: float) -> float:
        """Inverse of :meth:`phase` (the quadratic solved stably)."""
        a = 0.5 * self.f * self.d
        b = self.f * (1.0 + self.e0)
        c = self.phase0 - ph
        if a == 0.0:
            return -c / b
        disc = b * b - 4 * a * c
        return (2 * -c) / (b + math.sqrt(disc))
