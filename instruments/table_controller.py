"""Test-table controller (serial): positions the four axes, turns the rotary axis, reads resolvers.

Protocol (one reply line per command; angles in degrees, rates in deg/s):
  POS <axis> <deg>          slew axis 1..4 to a resolver reading           -> OK
  RATE <axis> <deg/s>       turn axis 2, 3 or 4 at a rate (max acceleration) -> OK
  RAMP <axis> <deg/s^2> <deg/s>  change the rate at a commanded acceleration -> OK
  STOP [<axis>]             decelerate to rest                               -> OK
  HOME                      all axes to 0 deg                                -> OK
  POS? <axis>               resolver reading (axes 2-4 wrapped to [0, 360))
  RATE? <axis>              present rate
  STAT? [<axis>]            HOLD | MOVING | SETTLING | ACCEL | ROTATING (all four if no axis)
  ILCK?                     interlock state: CLOSED (safe to run) or OPEN
  PPR <n> / PPR?            rotary pulse output, pulses per revolution (1..3600)
"""

from __future__ import annotations

import math

from instruments.base import ByteInstrument, InstrumentError, as_float, as_int, need
from sim.table import AXES, CONTINUOUS, TableError
from sim.world import World


class TableController(ByteInstrument):
    ident = "ISU-LAB,TT-4AX,0,1.0"

    def __init__(self, name: str, world: World, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.table = world.table
        self.interlock_closed = True
        # fault injection: axes that accept commands but do not move (a stalled drive)
        self.stalled: set[int] = set()

    def _axis(self, x: str) -> int:
        return as_int(x, "axis", 1, 4)

    def _apply(self, fn, *a) -> str:
        if not self.interlock_closed:
            raise InstrumentError(15, "interlock open: motion inhibited")
        try:
            fn(*a, self.world.now)
        except TableError as e:
            raise InstrumentError(13, str(e)) from None
        self.world.changed()
        return "OK"

    def command(self, cmd: str, args: list[str]):
        tb = self.table
        if cmd == "POS":
            need(args, 2, "POS <axis> <deg>")
            ax = self._axis(args[0])
            deg = as_float(args[1], "angle")
            if ax in CONTINUOUS:
                deg %= 360.0
            if ax in self.stalled:
                return "OK"
            return self._apply(tb.move, ax, math.radians(deg))
        if cmd == "RATE":
            need(args, 2, "RATE <axis> <deg/s>")
            ax = self._axis(args[0])
            if ax not in CONTINUOUS:
                raise InstrumentError(12, f"axis {ax} cannot rotate continuously")
            rate = math.radians(as_float(args[1], "rate"))
            if ax in self.stalled:
                return "OK"
            return self._apply(tb.rotate, ax, rate)
        if cmd == "RAMP":
            need(args, 3, "RAMP <axis> <deg/s^2> <deg/s>")
            ax = self._axis(args[0])
            if ax not in CONTINUOUS:
                raise InstrumentError(12, f"axis {ax} cannot rotate continuously")
            acc = math.radians(as_float(args[1], "acceleration"))
            rate = math.radians(as_float(args[2], "rate"))
            if ax in self.stalled:
                return "OK"
            return self._apply(lambda a, r, c, t: tb.rotate(a, r, t, accel=c), ax, rate, acc)
        if cmd == "STOP":
            axes = [self._axis(args[0])] if args else list(AXES)
            for ax in axes:
                tb.stop(ax, self.world.now)
            self.world.changed()
            return "OK"
        if cmd == "HOME":
            for ax in AXES:
                self._apply(tb.move, ax, 0.0)
            return "OK"
        if cmd == "POS?":
            need(args, 1, "POS? <axis>")
            ax = self._axis(args[0])
            deg = math.degrees(tb.resolver(ax, self.world.now))
            if ax in CONTINUOUS:
                deg %= 360.0
            return f"{deg:.7f}"
        if cmd == "RATE?":
            need(args, 1, "RATE? <axis>")
            _, v, _ = tb.axes[self._axis(args[0])].state(self.world.now)
            return f"{math.degrees(v):.7f}"
        if cmd == "STAT?":
            axes = [self._axis(args[0])] if args else list(AXES)
            return ",".join(tb.status(ax, self.world.now) for ax in axes)
        if cmd == "ILCK?":
            return "CLOSED" if self.interlock_closed else "OPEN"
        if cmd == "PPR":
            need(args, 1, "PPR <pulses per revolution>")
            tb.pulses_per_rev = as_int(args[0], "pulses per revolution", 1, 3600)
            self.world.changed()
            return "OK"
        if cmd == "PPR?":
            return str(tb.pulses_per_rev)
        return super().command(cmd, args)
