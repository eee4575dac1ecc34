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
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any

import simpy

from instruments.base import ByteInstrument, Deferred, InstrumentError, as_int
from sim.cigtf.world import CigtfWorld
from sim.timebase import ticks


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
