"""Serial instruments of the CIGTF gyrocompassing station (report 001, section 3).

Fixture programmer (axes V = vertical, H = horizontal; whole degrees only, the inductosyn
nulls):
  MOVE <V|H> <deg>    slew the axis to the null 0..359                 -> OK
  TURN <V|H> <deg>    turn the axis by -360..360 whole degrees          -> OK
  POS?                commanded nulls "<v> <h>"
  STAT?               HOLD | MOVING | FAULT
DVM / averager:
  AVG?                one 10-s electronically averaged torquer current, mA, answered
                      after the 10 s of averaging
  APER?               averaging time, s
Gyro power control:
  PWR ON | PWR OFF    -> OK
  PWR?                ON <seconds since turn-on> | OFF
  VOLT <volts>        the spin motor's supply, 10..40 V (error 12 outside), set with the
                      gyro off (error 18 while on)                      -> OK
  VOLT?               the supply's setting, volts, 2 decimals
Set-up aids (section 4.1, sim/cigtf/setup.py; refused while an axis moves, error 16):
  LEVEL?              the EW and NS bubble levels on the vertical axis, "<ew> <ns>" arcsec
  TILT <EW|NS> <arcsec>  levelling screws: that level at vertical 0 to read so much more
                      (-600..600)                                       -> OK
  AZIM?               the autocollimator on the horizontal axis's mirror, arcsec from the
                      north reference, positive west (error 13 outside its +-3600 field)
  BASE <arcsec>       base azimuth adjustment: the autocollimator to read so much more
                      (-3600..3600)                                     -> OK
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any

import simpy

from instruments.base import (
    ByteInstrument,
    Deferred,
    InstrumentError,
    as_choice,
    as_int,
    as_real_in,
)
from sim.cigtf.setup import SetupAids
from sim.cigtf.world import CigtfWorld
from sim.timebase import ticks

ROTOR_V_MIN, ROTOR_V_MAX = 10.0, 40.0  # the spin motor supply's range (nominal 26 V)


def _axis(x: str) -> str:
    a = x.upper()
    if a not in ("V", "H"):
        raise InstrumentError(12, f"axis must be V or H, got '{x[:10]}'")
    return a


class FixtureProgrammer(ByteInstrument):
    ident = "CIGTF,GOERZ-2AX-PROGRAMMER,0,1.0"

    def __init__(self, name: str, world: CigtfWorld, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.fail_moves = False  # fault injection: the drive stops short, status FAULT
        self.fault = False
        self.define("MOVE <V|H> <deg>", lambda a: self._move("MOVE", a))
        self.define("TURN <V|H> <deg>", lambda a: self._move("TURN", a))
        self.define("POS?", self._pos_q)
        self.define("STAT?", self._stat)

    def on_clear(self) -> None:
        self.fault = False  # *CLS clears a latched drive fault

    def _go(self, v: int, h: int) -> str:
        if self.world.now < self.world.moving_until:
            raise InstrumentError(16, "busy: axis still moving")
        if self.fault:
            raise InstrumentError(17, "drive fault: clear with *CLS")
        self.world.start_move(v, h, arrive=not self.fail_moves)
        self.fault = self.fail_moves
        return "OK"

    def _move(self, cmd: str, args: list[str]) -> str:
        fx = self.world.fixture
        ax = _axis(args[0])
        lo, hi = (0, 359) if cmd == "MOVE" else (-360, 360)
        deg = as_int(args[1], "angle (whole degrees)", lo, hi)
        v, h = fx.vertical_deg, fx.horizontal_deg
        if ax == "V":
            v = deg if cmd == "MOVE" else v + deg
        else:
            h = deg if cmd == "MOVE" else h + deg
        return self._go(v % 360, h % 360)

    def _pos_q(self, _: list[str]) -> str:
        fx = self.world.fixture
        return f"{fx.vertical_deg} {fx.horizontal_deg}"

    def _stat(self, _: list[str]) -> str:
        if self.world.now < self.world.moving_until:
            return "MOVING"
        return "FAULT" if self.fault else "HOLD"


class AveragingDvm(ByteInstrument):
    ident = "CIGTF,DVM-AVERAGER,0,1.0"

    def __init__(self, name: str, world: CigtfWorld, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.define("AVG?", self._avg)
        self.define("APER?", lambda _: f"{world.p.average_s:g}")

    def _avg(self, _: list[str]) -> Deferred:
        d = Deferred(self.env)
        self.env.process(self._average(d))
        return d

    def _average(self, d: Deferred) -> Generator[simpy.Event, Any, None]:
        t0 = self.world.now
        yield self.env.timeout(ticks(self.world.p.average_s)) | d.cancel_event
        if d.cancelled:  # a *CLS dropped the query: the average is abandoned
            return
        try:
            d.resolve(f"{self.world.average_current_ma(t0, self.world.now):.7f}")
        except Exception as e:  # noqa: BLE001 - a fault of the simulation, named
            d.resolve(self.internal_error("AVG?", e))


class GyroPower(ByteInstrument):
    ident = "CIGTF,GYRO-POWER,0,1.0"

    def __init__(self, name: str, world: CigtfWorld, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.define("PWR ON|OFF", self._pwr)
        self.define("PWR?", self._pwr_q)
        self.define("VOLT <volts>", self._volt)
        self.define("VOLT?", lambda _: f"{self.world.p.rotor_voltage_v:.2f}")

    def _volt(self, args: list[str]) -> str:
        v = as_real_in(args[0], "rotor voltage, V", ROTOR_V_MIN, ROTOR_V_MAX)
        if self.world.gyro.on_since is not None:
            raise InstrumentError(18, "rotor voltage: turn the gyro power off first")
        self.world.set_rotor_voltage(v)
        return "OK"

    def _pwr(self, args: list[str]) -> str:
        what = args[0].upper()
        if what == "ON":
            self.world.power_on()
        elif what == "OFF":
            self.world.power_off()
        else:
            raise InstrumentError(12, f"PWR takes ON or OFF, got '{args[0][:10]}'")
        return "OK"

    def _pwr_q(self, _: list[str]) -> str:
        on = self.world.gyro.on_since
        return "OFF" if on is None else f"ON {self.world.now - on:.1f}"


FIELD_ARCSEC = 3600.0  # the autocollimator's field: the mirror within 1 deg of its axis


class SetupAidsInstrument(ByteInstrument):
    ident = "CIGTF,SETUP-AIDS,0,1.0"

    def __init__(self, name: str, world: CigtfWorld, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.define("LEVEL?", lambda _: "{:.1f} {:.1f}".format(*self._still().levels_arcsec()))
        self.define("AZIM?", self._azim)
        self.define("TILT <EW|NS> <arcsec>", self._tilt)
        self.define("BASE <arcsec>", self._base)

    def _still(self) -> SetupAids:
        if self.world.now < self.world.moving_until:
            raise InstrumentError(16, "busy: axis still moving")
        return self.world.aids

    def _azim(self, _: list[str]) -> str:
        x = self._still().azimuth_arcsec()
        if abs(x) > FIELD_ARCSEC:
            raise InstrumentError(13, "no return: the mirror is outside the autocollimator's "
                                  "field")
        return f"{x:.1f}"

    def _tilt(self, args: list[str]) -> str:
        level = as_choice(args[0], "level", ("EW", "NS"))
        x = as_real_in(args[1], "tilt, arcsec", -600.0, 600.0)
        self._still().tilt(level, x)
        self.world.adjusted()
        return "OK"

    def _base(self, args: list[str]) -> str:
        x = as_real_in(args[0], "base turn, arcsec", -3600.0, 3600.0)
        self._still().turn_base(x)
        self.world.adjusted()
        return "OK"
