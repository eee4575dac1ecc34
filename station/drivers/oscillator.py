"""Driver of the master oscillator's panel."""

from __future__ import annotations

from station.drivers.serial_base import SerialDriver


class OscillatorDriver(SerialDriver):
    def nominal_hz(self) -> float:
        return float(self.query("FREQ?"))

    def divider(self, output: int) -> int:
        return int(self.query(f"DIV? {output}"))

    def s_t(self, output: int) -> float:
        """Nominal seconds per pulse of countdown output 1 (S1^T) or 2 (S2^T)."""
        return self.divider(output) / self.nominal_hz()

    def status(self) -> str:
        return self.query("STAT?")

    def self_test(self) -> str:
        return self.query("TEST?")
