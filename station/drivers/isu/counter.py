"""Driver of one frequency counter ("measure Z" / "measure X-Y")."""

from __future__ import annotations

from station.clock import Clock
from station.drivers.replies import PASS, Form, integer, word
from station.drivers.serial_base import SerialDriver
from station.errors import DriverError

MODES = {"measure Z": "Z", "measure X-Y": "XY"}
# The count register: 12 decimal digits (the preset reaches 10^11), signed in "measure Z"
# (X-Y may be negative); "measure X-Y" counts clock ticks, never negative.
REGISTER = 10**12 - 1
MAX_PRESET = 10**11
QUEUE = 256  # readings the counter queues (docs/protocols.md)
READING = Form([integer("count", -REGISTER, REGISTER)])
QUEUED = Form([integer("readings queued", 0, QUEUE)])
STATE = Form([word("state", "OPER", "STBY")])


class CounterDriver(SerialDriver):
    model = ("ISU-LAB", "FC-1")

    def __init__(self, name: str, url: str, clock: Clock | None = None,
                 timeout: float = 5.0) -> None:
        super().__init__(name, url, clock, timeout)
        self.mode: str | None = None  # "Z" or "XY" as last set; None until set

    def set_mode(self, mode: str) -> None:
        """``mode`` as the lab names it: "measure Z" or "measure X-Y"."""
        if mode not in MODES:
            raise DriverError(self.name, self.url, f"unknown counter mode {mode!r}")
        self.mode = None
        self.command(f"MODE {MODES[mode]}")
        self.mode = MODES[mode]

    def set_preset(self, n: int) -> None:
        self.command(f"PRESET {self.whole(n, 'preset', 1, MAX_PRESET)}")

    def operate(self) -> None:
        self.command("OPER")

    def standby(self) -> None:
        self.command("STBY")

    def state(self) -> str:
        return self.ask("STATE?", STATE)[0]

    def read(self, timeout: float) -> int:
        """Wait up to ``timeout`` seconds for the next reading (the counter's print-out)."""
        n = self.ask("READ?", READING, timeout=timeout)[0]
        if n < 0 and self.mode == "XY":
            raise self.refuse("READ?", "a negative count of clock ticks in measure X-Y")
        return n

    def discard_readings(self) -> None:
        """Drop readings queued from earlier gates (print-and-continue keeps producing them)."""
        self.command("CLR")

    def queued(self) -> int:
        return self.ask("COUN?", QUEUED)[0]

    def self_test(self) -> str:
        self.ask("TEST?", PASS)
        return "PASS"
