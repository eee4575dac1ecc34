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
# the set-up aids (section 4.1): bubble levels and autocollimator, arcsec to 0.1
LEVELS = Form([fixed("EW level, arcsec", 1, -3600.0, 3600.0),
               fixed("NS level, arcsec", 1, -3600.0, 3600.0)])
AZIMUTH = Form([fixed("horizontal axis azimuth, arcsec", 1, -3600.0, 3600.0)])
ROTOR_V_RANGE = (10.0, 40.0)  # the spin motor supply's settings (nominal 26 V)
ROTOR_VOLTAGE = Form([fixed("rotor voltage, V", 2, *ROTOR_V_RANGE)])
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

    def set_rotor_voltage(self, volts: float) -> None:
        """The spin motor's supply, volts (10..40; the gyro must be off): section 1's
        rotor-voltage variation."""
        lo, hi = ROTOR_V_RANGE
        if not lo <= volts <= hi:
            raise DriverError(self.name, self.url, f"rotor voltage {volts!r}: {lo:g}..{hi:g} V")
        self.command(f"VOLT {volts:.2f}")

    def rotor_voltage(self) -> float:
        """The supply's setting, volts."""
        return self.ask("VOLT?", ROTOR_VOLTAGE)[0]


class SetupAidsDriver(SerialDriver):
    """Bubble levels, levelling screws, autocollimator and base adjustment (section 4.1)."""

    model = ("CIGTF", "SETUP-AIDS")

    def levels(self) -> tuple[float, float]:
        """(EW, NS) bubble-level readings, arcsec."""
        ew, ns = self.ask("LEVEL?", LEVELS)
        return ew, ns

    def azimuth(self) -> float:
        """The autocollimator's reading of the horizontal axis's mirror, arcsec."""
        return self.ask("AZIM?", AZIMUTH)[0]

    def tilt(self, level: str, arcsec: float) -> None:
        """Levelling screws: the ``level`` (EW or NS) at vertical 0 to read more by this."""
        if level not in ("EW", "NS") or not -600.0 <= arcsec <= 600.0:
            raise DriverError(self.name, self.url, f"tilt {level} {arcsec!r}: level EW or NS, "
                              "at most 600 arcsec")
        self.command(f"TILT {level} {arcsec:.2f}")

    def turn_base(self, arcsec: float) -> None:
        """Base azimuth adjustment: the autocollimator to read more by this."""
        if not -3600.0 <= arcsec <= 3600.0:
            raise DriverError(self.name, self.url, f"base turn {arcsec!r} arcsec: at most "
                              "3600")
        self.command(f"BASE {arcsec:.2f}")


@dataclass
class CigtfDrivers(DriverSet):
    """What a CIGTF procedure sees: fixture programmer, DVM, gyro power supply, set-up
    aids, clock."""

    fixture: FixtureDriver
    dvm: DvmDriver
    power: GyroPowerDriver
    aids: SetupAidsDriver

    instrument_of: ClassVar[dict[str, str]] = {"power": "gyro_power", "aids": "setup_aids"}
