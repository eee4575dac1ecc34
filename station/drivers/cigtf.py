"""Drivers of the CIGTF gyrocompassing station: fixture programmer, DVM, gyro power."""

from __future__ import annotations

from station.clock import Clock
from station.drivers.serial_base import SerialDriver
from station.errors import DriverError, LinkTimeout


class FixtureDriver(SerialDriver):
    def __init__(self, url: str, clock: Clock, name: str = "fixture", timeout: float = 5.0):
        super().__init__(name, url, timeout)
        self.clock = clock

    def move(self, axis: str, deg: int) -> None:
        self.command(f"MOVE {axis} {int(deg)}")

    def turn(self, axis: str, deg: int) -> None:
        self.command(f"TURN {axis} {int(deg)}")

    def position(self) -> tuple[int, int]:
        v, h = self.numbers("POS?", 2)
        return int(v), int(h)

    def status(self) -> str:
        return self.query("STAT?")

    def wait_hold(self, timeout: float = 120.0, poll: float = 1.0) -> None:
        """Wait until both axes hold on their nulls; a drive fault raises at once."""
        t_end = self.clock.now() + timeout
        while True:
            st = self.status()
            if st == "HOLD":
                return
            if st == "FAULT":
                raise DriverError(self.name, self.url, "drive fault: axis did not reach its null")
            if self.clock.now() >= t_end:
                raise LinkTimeout(self.name, self.url, f"axes still {st} after {timeout:g} s")
            self.clock.sleep(poll)


class DvmDriver(SerialDriver):
    def __init__(self, url: str, name: str = "dvm", timeout: float = 5.0):
        super().__init__(name, url, timeout)

    def aperture(self) -> float:
        return float(self.query("APER?"))

    def average(self, aperture_s: float = 10.0) -> float:
        """One averaged torquer current, mA (the reply comes after the averaging time)."""
        reply = self.query("AVG?", timeout=aperture_s + self.timeout)
        try:
            return float(reply)
        except ValueError:
            raise DriverError(self.name, self.url, f"bad reading {reply!r}") from None


class GyroPowerDriver(SerialDriver):
    def __init__(self, url: str, name: str = "gyro_power", timeout: float = 5.0):
        super().__init__(name, url, timeout)

    def on(self) -> None:
        self.command("PWR ON")

    def off(self) -> None:
        self.command("PWR OFF")

    def status(self) -> tuple[bool, float]:
        """(on, seconds since turn-on)."""
        r = self.query("PWR?").split()
        if r[0] == "OFF":
            return False, 0.0
        return True, float(r[1])
