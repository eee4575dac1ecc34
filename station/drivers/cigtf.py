"""Drivers of the CIGTF gyrocompassing station: fixture programmer, DVM, gyro power."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from station.drivers.driver_set import DriverSet
from station.drivers.replies import Form, OneOf, fixed, general, integer, literal, word
from station.drivers.serial_base import SerialDriver
from station.errors import DriverError, LinkTimeout

NULLS = Form([integer("vertical null, deg", 0, 359), integer("horizontal null, deg", 0, 359)])
FIXTURE_STATUS = Form([word("fixture state", "HOLD", "MOVING", "FAULT")])
# The DVM's range: no torquer current of the gyro (S_T = 1 deg/hr per mA: Earth rate and
# drift make a few tens of mA at most) comes near 100 mA (docs/protocols.md, CIGTF).
DVM_RANGE_MA = 100.0
CURRENT = Form([fixed("torquer current, mA", 7, -DVM_RANGE_MA, DVM_RANGE_MA)])
APERTURE = Form([general("averaging time, s", 0.001, 3600.0)])
POWER = OneOf(Form([literal("OFF")]),
              Form([literal("ON"), fixed("seconds since turn-on", 1, 0.0, 1e9)]))


class FixtureDriver(SerialDriver):
    model = ("CIGTF", "GOERZ-2AX-PROGRAMMER")

    def move(self, axis: str, deg: int) -> None:
        self.command(f"MOVE {axis} {self.whole(deg, 'null angle', 0, 359)}")

    def turn(self, axis: str, deg: int) -> None:
        self.command(f"TURN {axis} {self.whole(deg, 'turn angle', -360, 360)}")

    def position(self) -> tuple[int, int]:
        v, h = self.ask("POS?", NULLS)
        return v, h

    def status(self) -> str:
        return self.ask("STAT?", FIXTURE_STATUS)[0]

    def wait_hold(self, timeout: float = 120.0, poll: float = 1.0) -> None:
        """Wait until both axes hold on their nulls; a drive fault raises at once."""
        clock = self.needs_clock()
        t_end = clock.now() + timeout
        while True:
            st = self.status()
            if st == "HOLD":
                return
            if st == "FAULT":
                raise DriverError(self.name, self.url, "drive fault: axis did not reach its null")
            if clock.now() >= t_end:
                raise LinkTimeout(self.name, self.url, f"axes still {st} after {timeout:g} s")
            clock.sleep(poll)


class DvmDriver(SerialDriver):
    model = ("CIGTF", "DVM-AVERAGER")

    def aperture(self) -> float:
        return self.ask("APER?", APERTURE)[0]

    def average(self, aperture_s: float = 10.0) -> float:
        """One averaged torquer current, mA (the reply comes after the averaging time)."""
        return self.ask("AVG?", CURRENT, timeout=aperture_s + self.timeout)[0]


class GyroPowerDriver(SerialDriver):
    model = ("CIGTF", "GYRO-POWER")

    def on(self) -> None:
        self.command("PWR ON")

    def off(self) -> None:
        self.command("PWR OFF")

    def status(self) -> tuple[bool, float]:
        """(on, seconds since turn-on)."""
        which, values = self.ask("PWR?", POWER)
        return (False, 0.0) if which == 0 else (True, values[0])


@dataclass
class CigtfDrivers(DriverSet):
    """What a CIGTF procedure sees: fixture programmer, DVM, gyro power supply, clock."""

    fixture: FixtureDriver
    dvm: DvmDriver
    power: GyroPowerDriver

    instrument_of: ClassVar[dict[str, str]] = {"power": "gyro_power"}
