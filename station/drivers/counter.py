"""Driver of one frequency counter ("measure Z" / "measure X-Y")."""

from __future__ import annotations

from station.drivers.serial_base import SerialDriver
from station.errors import DriverError

MODES = {"measure Z": "Z", "measure X-Y": "XY"}


class CounterDriver(SerialDriver):
    def set_mode(self, mode: str) -> None:
        """``mode`` as the lab names it: "measure Z" or "measure X-Y"."""
        if mode not in MODES:
            raise DriverError(self.name, self.url, f"unknown counter mode {mode!r}")
        self.command(f"MODE {MODES[mode]}")

    def set_preset(self, n: int) -> None:
        self.command(f"PRESET {int(n)}")

    def operate(self) -> None:
        self.command("OPER")

    def standby(self) -> None:
        self.command("STBY")

    def state(self) -> str:
        return self.query("STATE?")

    def read(self, timeout: float) -> int:
        """Wait up to ``timeout`` seconds for the next reading (the counter's print-out)."""
        reply = self.query("READ?", timeout=timeout)
        try:
            return int(reply)
        except ValueError:
            raise DriverError(self.name, self.url, f"reading is not a count: {reply!r}") from None

    def discard_readings(self) -> None:
        """Drop readings queued from earlier gates (print-and-continue keeps producing them)."""
        self.command("CLR")

    def queued(self) -> int:
        return int(self.query("COUN?"))

    def self_test(self) -> str:
        return self.query("TEST?")
