"""Driver of the four-axis test-table controller."""

from __future__ import annotations

from station.clock import Clock
from station.drivers.serial_base import SerialDriver
from station.errors import LinkTimeout


class TableDriver(SerialDriver):
    def __init__(self, url: str, clock: Clock, name: str = "table", timeout: float = 5.0):
        super().__init__(name, url, timeout)
        self.clock = clock

    def move(self, axis: int, deg: float) -> None:
        self.command(f"POS {axis} {deg:.7f}")

    def rotate(self, axis: int, rate_deg_s: float) -> None:
        self.command(f"RATE {axis} {rate_deg_s:.7f}")

    def ramp(self, axis: int, accel_deg_s2: float, rate_deg_s: float) -> None:
        self.command(f"RAMP {axis} {accel_deg_s2:.7f} {rate_deg_s:.7f}")

    def stop(self, axis: int | None = None) -> None:
        self.command("STOP" if axis is None else f"STOP {axis}")

    def home(self) -> None:
        self.command("HOME")

    def position(self, axis: int) -> float:
        return float(self.query(f"POS? {axis}"))

    def positions(self) -> tuple[float, float, float, float]:
        return tuple(self.position(a) for a in (1, 2, 3, 4))  # type: ignore[return-value]

    def rate(self, axis: int) -> float:
        return float(self.query(f"RATE? {axis}"))

    def status(self) -> list[str]:
        return self.query("STAT?").split(",")

    def interlock(self) -> str:
        return self.query("ILCK?")

    def set_pulses_per_rev(self, n: int) -> None:
        self.command(f"PPR {n}")

    def wait_still(self, timeout: float = 120.0, poll: float = 0.5) -> None:
        """Wait until every axis is holding or turning at its commanded rate."""
        t_end = self.clock.now() + timeout
        while True:
            st = self.status()
            if all(s in ("HOLD", "ROTATING") for s in st):
                return
            if self.clock.now() >= t_end:
                late = [f"axis {i} ({s})" for i, s in enumerate(st, start=1)
                        if s not in ("HOLD", "ROTATING")]
                raise LinkTimeout(
                    self.name, self.url,
                    f"{', '.join(late)} not settled after {timeout:g} s; STAT? {','.join(st)}",
                )
            self.clock.sleep(poll)
