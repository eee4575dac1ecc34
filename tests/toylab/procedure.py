"""The toy laboratory's one check-sheet: T-1, the bath temperature from n readings."""

from __future__ import annotations

import math

from procedures.runner import Run
from toylab.rack import ToyDrivers


def bath_temperature(st: ToyDrivers, run: Run, n: int = 10, interval_s: float = 1.0) -> dict:
    with run.sheet("T-1", "Bath temperature") as sh:
        with sh.step("1", f"{n} thermometer readings, {interval_s:g} s apart") as s:
            values = []
            for _ in range(n):
                values.append(st.thermometer.temperature_k())
                st.clock.sleep(interval_s)
            s.reading = {"readings_k": values}
        with sh.step("2", "mean and its standard error") as s:
            mean = sum(values) / n
            var = sum((v - mean) ** 2 for v in values) / (n - 1)
            s.reading = {"mean_k": mean, "sigma_k": math.sqrt(var / n)}
    return s.reading
