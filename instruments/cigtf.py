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

from instruments.base import ByteInstrument, Deferred, InstrumentError, as_int, need
from sim.cigtf_world import CigtfWorld
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

    def _go(self, v: int, h: int) -> str:
        if self.world.now < self.world.moving_until:
            raise InstrumentError(16, "busy: axis still moving")
        if self.fault:
            raise InstrumentError(17, "drive fault: clear with *CLS")
        self.world.start_move(v, h, arrive=not self.fail_moves)
        self.fault = self.fail_moves
        return "OK"

    def execute(self, line: str):
        if line.strip().upper() in ("*CLS", "DCL"):
            self.fault = False
        return super().execute(line)

    def command(self, cmd: str, args: list[str]):
        fx = self.world.fixture
        if cmd in ("MOVE", "TURN"):
            need(args, 2, f"{cmd} <V|H> <deg>")
            ax = _axis(args[0])
            lo, hi = (0, 359) if cmd == "MOVE" else (-360, 360)
            deg = as_int(args[1], "angle (whole degrees)", lo, hi)
            v, h = fx.vertical_deg, fx.horizontal_deg
            if ax == "V":
                v = deg if cmd == "MOVE" else v + deg
            else:
                h = deg if cmd == "MOVE" else h + deg
            return self._go(v % 360, h % 360)
        if cmd == "POS?":
            return f"{fx.vertical_deg} {fx.horizontal_deg}"
        if cmd == "STAT?":
            if self.world.now < self.world.moving_until:
                return "MOVING"
            return "FAULT" if self.fault else "HOLD"
        return super().command(cmd, args)


class AveragingDvm(ByteInstrument):
    ident = "CIGTF,DVM-AVERAGER,0,1.0"

    def __init__(self, name: str, world: CigtfWorld, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world

    def command(self, cmd: str, args: list[str]):
        if cmd == "AVG?":
            need(args, 0, "AVG?")
            d = Deferred(self.env)
            self.env.process(self._average(d))
            return d
        if cmd == "APER?":
            return f"{self.world.p.average_s:g}"
        return super().command(cmd, args)

    def _average(self, d: Deferred):
        t0 = self.world.now
        yield self.env.timeout(ticks(self.world.p.average_s))
        d.resolve(f"{self.world.average_current_ma(t0, self.world.now):.7f}")


class GyroPower(ByteInstrument):
    ident = "CIGTF,GYRO-POWER,0,1.0"

    def __init__(self, name: str, world: CigtfWorld, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world

    def command(self, cmd: str, args: list[str]):
        if cmd == "PWR":
            need(args, 1, "PWR ON|OFF")
            what = args[0].upper()
            if what == "ON":
                self.world.power_on()
            elif what == "OFF":
                self.world.power_off()
            else:
                raise InstrumentError(12, f"PWR takes ON or OFF, got '{args[0][:10]}'")
            return "OK"
        if cmd == "PWR?":
            on = self.world.gyro.on_since
            return "OFF" if on is None else f"ON {self.world.now - on:.1f}"
        return super().command(cmd, args)
