"""Test-table controller (serial): positions the four axes, turns the rotary axis, reads resolvers.

Protocol (one reply line per command; angles in degrees, rates in deg/s):
  POS <axis> <deg>          slew axis 1..4 to a resolver reading, |deg| <= 3600 -> OK
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
from collections.abc import Callable

from instruments.base import ByteInstrument, InstrumentError, as_float, as_int, as_real_in
from sim.isu.table import AXES, CONTINUOUS, TableError
from sim.isu.world import World

# A seized axis commanded to a reading within this of where it stands has nothing to do
# (the servo's in-position band: resolver error and setting scatter are a few arcsec).
IN_POSITION_ARCSEC = 10.0
MAX_ANGLE_DEG = 3600.0  # largest |POS| angle: ten turns (the modulo still keeps 1e-8 arcsec)


class TableController(ByteInstrument):
    ident = "ISU-LAB,TT-4AX,0,1.0"

    def __init__(self, name: str, world: World, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.table = world.table
        self.interlock_closed = True
        # fault injection: axes that accept commands but do not move (a seized drive), and
        # the status each reports while a command it cannot carry out is pending
        self.stalled: set[int] = set()
        self._stuck: dict[int, str] = {}
        self._define_protocol()

    def stall(self, axis: int) -> None:
        """Seize ``axis``'s drive now: it comes to rest and no longer follows commands."""
        tb, now = self.table, self.world.now
        was = tb.status(axis, now)
        self.stalled.add(axis)
        if was != "HOLD":  # caught mid-command: the axis stops short of what it was asked
            tb.stop(axis, now)
            self.world.changed()
            self._stuck[axis] = "ACCEL" if was in ("ACCEL", "ROTATING") else "MOVING"

    def _stalled_command(self, axis: int, target_deg: float | None, rate: float = 0.0,
                         accel: float | None = None) -> str:
        """Accept a command for a seized axis: it stays put, reporting motion if any was asked."""
        if not self.interlock_closed:
            raise InstrumentError(15, "interlock open: motion inhibited")
        try:  # the controller still refuses what the table could never do
            if target_deg is None:
                self.table.check_rate(axis, rate, accel)
            else:
                self.table.check_move(axis, math.radians(target_deg))
        except TableError as e:
            raise InstrumentError(13, str(e)) from None
        if target_deg is not None:
            here = math.degrees(self.table.resolver(axis, self.world.now))
            off = here - target_deg
            if axis in CONTINUOUS:
                off = (off + 180.0) % 360.0 - 180.0
            moving = abs(off) * 3600.0 > IN_POSITION_ARCSEC
            status = "MOVING"
        else:
            moving, status = rate != 0.0, "ACCEL"
        if moving:
            self._stuck[axis] = status
        else:
            self._stuck.pop(axis, None)
        return "OK"

    def _status(self, axis: int) -> str:
        return self._stuck.get(axis) or self.table.status(axis, self.world.now)

    def _axis(self, x: str) -> int:
        return as_int(x, "axis", 1, 4)

    def _angle(self, x: str) -> float:
        # a resolver reading: beyond ten turns the modulo would lose the arcsec
        return as_real_in(x, "angle", -MAX_ANGLE_DEG, MAX_ANGLE_DEG)

    def _apply(self, fn: Callable[..., object], *a: float) -> str:
        """A motion command ``fn(*a, now)`` on the table, refused while the interlock is open."""
        if not self.interlock_closed:
            raise InstrumentError(15, "interlock open: motion inhibited")
        try:
            fn(*a, self.world.now)
        except TableError as e:
            raise InstrumentError(13, str(e)) from None
        self.world.changed()
        return "OK"

    def _define_protocol(self) -> None:
        for usage, action in (
            ("POS <axis> <deg>", self._pos),
            ("RATE <axis> <deg/s>", self._rate),
            ("RAMP <axis> <deg/s^2> <deg/s>", self._ramp),
            ("STOP [<axis>]", self._stop),
            ("HOME", self._home),
            ("POS? <axis>", self._pos_q),
            ("RATE? <axis>", self._rate_q),
            ("STAT? [<axis>]", self._stat_q),
            ("ILCK?", lambda _: "CLOSED" if self.interlock_closed else "OPEN"),
            ("PPR <pulses per revolution>", self._ppr),
            ("PPR?", lambda _: str(self.table.pulses_per_rev)),
        ):
            self.define(usage, action)

    def _pos(self, args: list[str]) -> str:
        ax = self._axis(args[0])
        deg = self._angle(args[1])
        if ax in CONTINUOUS:
            deg %= 360.0
        if ax in self.stalled:
            return self._stalled_command(ax, deg)
        return self._apply(self.table.move, ax, math.radians(deg))

    def _continuous(self, x: str) -> int:
        ax = self._axis(x)
        if ax not in CONTINUOUS:
            raise InstrumentError(12, f"axis {ax} cannot rotate continuously")
        return ax

    def _rate(self, args: list[str]) -> str:
        ax = self._continuous(args[0])
        rate = math.radians(as_float(args[1], "rate"))
        if ax in self.stalled:
            return self._stalled_command(ax, None, rate)
        return self._apply(self.table.rotate, ax, rate)

    def _ramp(self, args: list[str]) -> str:
        ax = self._continuous(args[0])
        acc = math.radians(as_float(args[1], "acceleration"))
        rate = math.radians(as_float(args[2], "rate"))
        if ax in self.stalled:
            return self._stalled_command(ax, None, rate, acc)
        tb = self.table
        return self._apply(lambda a, r, c, t: tb.rotate(a, r, t, accel=c), ax, rate, acc)

    def _stop(self, args: list[str]) -> str:
        axes = [self._axis(args[0])] if args else list(AXES)
        for ax in axes:
            if ax in self.stalled:
                self._stuck.pop(ax, None)  # nothing to stop: the drive is not turning
            else:
                self.table.stop(ax, self.world.now)
        self.world.changed()
        return "OK"

    def _home(self, _: list[str]) -> str:
        if not self.interlock_closed:
            raise InstrumentError(15, "interlock open: motion inhibited")
        for ax in AXES:
            if ax in self.stalled:
                self._stalled_command(ax, 0.0)
            else:
                self._apply(self.table.move, ax, 0.0)
        return "OK"

    def _pos_q(self, args: list[str]) -> str:
        ax = self._axis(args[0])
        deg = math.degrees(self.table.resolver(ax, self.world.now))
        if ax in CONTINUOUS:
            deg %= 360.0
        return f"{deg:.7f}"

    def _rate_q(self, args: list[str]) -> str:
        _, v, _ = self.table.axes[self._axis(args[0])].state(self.world.now)
        return f"{math.degrees(v):.7f}"

    def _stat_q(self, args: list[str]) -> str:
        axes = [self._axis(args[0])] if args else list(AXES)
        return ",".join(self._status(ax) for ax in axes)

    def _ppr(self, args: list[str]) -> str:
        self.table.pulses_per_rev = as_int(args[0], "pulses per revolution", 1, 3600)
        self.world.changed()
        return "OK"
