"""Driver of the master oscillator's panel."""

from __future__ import annotations

from station.drivers.replies import PASS, Form, fixed, integer, word
from station.drivers.serial_base import SerialDriver

FREQUENCY = Form([fixed("nominal frequency, Hz", 1, 1.0, 1e9)])
DIVIDER = Form([integer("countdown ratio", 1, 10**9)])
STATUS = Form([word("status", "LOCKED")])


class OscillatorDriver(SerialDriver):
    model = ("ISU-LAB", "MO-5M")

    def nominal_hz(self) -> float:
        return self.ask("FREQ?", FREQUENCY)[0]

    def divider(self, output: int) -> int:
        k = self.whole(output, "countdown output", 1, 2)
        return self.ask(f"DIV? {k}", DIVIDER)[0]

    def s_t(self, output: int) -> float:
        """Nominal seconds per pulse of countdown output 1 (S1^T) or 2 (S2^T)."""
        return self.divider(output) / self.nominal_hz()

    def status(self) -> str:
        return self.ask("STAT?", STATUS)[0]

    def self_test(self) -> str:
        self.ask("TEST?", PASS)
        return "PASS"
