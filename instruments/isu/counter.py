"""Frequency counter with inputs X, Y (differenced) and Z, as used throughout report 000.

Modes, named as the lab names them:
* "measure Z"  (MODE Z):  the gate is PRESET pulses of Z; the reading is the X-Y count in it.
* "measure X-Y" (MODE XY): the gate is PRESET pulses of X-Y, opened and closed on their
  leading edges; the reading is the Z count (clock ticks) in it.
In OPER the counter opens its gate on the next leading edge of the gating train; on
reaching the preset it records the reading, clears and starts the next gate on the same
edge (print and continue) until STBY. Readings queue for the reader (READ? waits for one).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Generator
from typing import Any

import simpy

from instruments.base import ByteInstrument, Deferred, InstrumentError, as_int
from instruments.isu.patch_panel import PatchPanel
from sim.isu.pulses import PulseLine
from sim.isu.world import World
from sim.timebase import ticks_ceil

MAX_QUEUE = 256  # readings kept for the host
MAX_PRESET = 10**11
MODES = {"Z": "Z", "XY": "XY", "X-Y": "XY"}
# Time to hand one reading to the recorder (the print-out). The report gives no figure;
# the simulation takes 20 ms, so each gate must last at least this long: a gate that
# closes sooner is refused at OPER, or stops the counter (print overrun) if the world
# changes while it counts. It also bounds the work per simulated second (50 readings).
PRINT_S = 0.02
MIN_GATE_S = PRINT_S * (1 - 1e-6)  # the limit, blind to the oscillator's ppb offset


class FrequencyCounter(ByteInstrument):
    def __init__(self, name: str, jack: str, world: World, panel: PatchPanel, latency_s: float):
        super().__init__(name, world.env, latency_s)
        self.ident = f"ISU-LAB,FC-1,{jack},1.0"
        self.world = world
        self.panel = panel
        self.jack = jack
        self.mode = "Z"
        self.preset = 1000
        self.operating = False
        self.readings: deque[int] = deque()
        self.n_readings = 0
        self.gate_open: float | None = None
        self._waiters: deque[Deferred] = deque()
        self._proc: simpy.Process | None = None
        self._define_protocol()

    # ----- wiring -----
    def _inputs(self) -> tuple[PulseLine | None, PulseLine | None, PulseLine | None]:
        src = self.panel.source
        return src(self.jack, "X"), src(self.jack, "Y"), src(self.jack, "Z")

    def _difference_line(self, x: PulseLine | None, y: PulseLine | None) -> PulseLine:
        """The X-Y train as a gating line (measure X-Y)."""
        if x is None:
            raise InstrumentError(21, "input X not connected")
        if y is None:
            return x
        if x.net is not None and x.net is y.net and x.bipolar_sign == 1 and y.bipolar_sign == -1:
            return x.net
        raise InstrumentError(22, "X-Y gating needs X alone or the +/- lines of one gyro")

    # ----- measurement -----
    def _gate_line_and_reader(self) -> tuple[PulseLine, Callable[[float, float], int]]:
        x, y, z = self._inputs()
        if self.mode == "Z":
            if z is None:
                raise InstrumentError(21, "input Z not connected")
            if x is None:
                raise InstrumentError(21, "input X not connected")

            def read(t0: float, t1: float) -> int:
                return x.count(t0, t1) - (y.count(t0, t1) if y is not None else 0)

            return z, read
        gate = self._difference_line(x, y)
        if z is None:
            raise InstrumentError(21, "input Z not connected")
        return gate, lambda t0, t1: z.count(t0, t1)

    def _run(self) -> Generator[simpy.Event, Any, None]:
        try:
            yield from self._gates()
        except simpy.Interrupt:
            return
        except Exception as e:  # noqa: BLE001 - a fault of the simulation: stop, say what
            reply = self.internal_error("counting (OPER)", e)
            self._proc = None
            self.operating = False
            self.gate_open = None
            self._refuse_waiters(reply)

    def _gates(self) -> Generator[simpy.Event, Any, None]:
        world = self.world
        while self.operating:
            try:
                gate, read = self._gate_line_and_reader()
            except InstrumentError as e:
                self.log_error(e.code, e.text)
                yield world.change_event
                continue
            t_open = gate.edge_after(world.now, 1) if self.gate_open is None else self.gate_open
            if t_open is None or t_open > world.now:
                if t_open is None:
                    yield world.change_event
                    continue
                due = ticks_ceil(t_open)
                yield world.env.timeout(due - world.env.now) | world.change_event
                if world.env.now < due:  # compare ticks: t_open may lie inside the due tick
                    continue  # the world changed before the gate opened: re-plan
            self.gate_open = t_open
            # Sleep through most of a long gate on an estimate of its end; the exact
            # closing edge is solved near the end (or never, if standby comes first).
            est = gate.estimate_edge(t_open, self.preset)
            if est is not None:
                early = est - max(1.0, 0.02 * (est - t_open))
                if ticks_ceil(early) > world.env.now:
                    due = ticks_ceil(early)
                    yield world.env.timeout(due - world.env.now) | world.change_event
                    if not self.operating:
                        return
                    if world.env.now < due:
                        continue  # the world changed: plan again from the open edge
            t_close = gate.edge_after(t_open, self.preset)
            if t_close is None:
                yield world.change_event
                continue
            if t_close - t_open < MIN_GATE_S:
                self._overrun(t_close - t_open)
                return
            due = ticks_ceil(t_close)
            if due > world.env.now:
                yield world.env.timeout(due - world.env.now) | world.change_event
                if not self.operating:
                    return
                if world.env.now < due:
                    continue  # the world changed: recompute the closing edge
            if not self.operating:
                return
            self._record(read(t_open, t_close))
            self.gate_open = t_close

    def _overrun(self, gate_s: float) -> None:
        """A gate shorter than the print-out: the counter stops and says why."""
        text = (f"print overrun: gate of {self.preset} pulses lasted {gate_s:.3g} s, shorter "
                f"than the {PRINT_S:g} s print-out; counter in standby")
        self.log_error(25, text)
        self._proc = None
        self.operating = False
        self.gate_open = None
        self._refuse_waiters(f"ERR 25 {text}")

    def _record(self, value: int) -> None:
        self.n_readings += 1
        while self._waiters and self._waiters[0].cancelled:
            self._waiters.popleft()
        if self._waiters:
            self._waiters.popleft().resolve(str(value))
            return
        if len(self.readings) >= MAX_QUEUE:
            self.readings.popleft()
            self.log_error(24, "reading queue overflow")
        self.readings.append(value)

    # ----- protocol -----
    def _define_protocol(self) -> None:
        for usage, action in (
            ("*RST", self._reset),
            ("MODE Z|XY", self._mode),
            ("MODE?", lambda _: self.mode),
            ("PRESET <count>", self._preset),
            ("PRESET?", lambda _: str(self.preset)),
            ("OPER", self._oper),
            ("STBY", self._stby),
            ("STATE?", lambda _: "OPER" if self.operating else "STBY"),
            ("READ?", self._read),
            ("FETC?", lambda _: str(self.readings.popleft()) if self.readings else "NONE"),
            ("COUN?", lambda _: str(len(self.readings))),
            ("CLR", self._clr),
            ("TEST?", lambda _: "PASS"),
        ):
            self.define(usage, action)

    def _reset(self, _: list[str]) -> str:
        self._standby("*RST")
        self.mode, self.preset = "Z", 1000
        self.readings.clear()
        return "OK"

    def _mode(self, args: list[str]) -> str:
        m = args[0].upper()
        if m not in MODES:
            raise InstrumentError(11, f"mode must be Z or XY, got '{args[0][:10]}'")
        if self.operating:
            raise InstrumentError(23, "set STBY before changing mode")
        self.mode = MODES[m]
        return "OK"

    def _preset(self, args: list[str]) -> str:
        n = as_int(args[0], "preset", 1, MAX_PRESET)
        if self.operating:
            raise InstrumentError(23, "set STBY before changing the preset")
        self.preset = n
        return "OK"

    def _oper(self, _: list[str]) -> str:
        if self.operating:
            return "OK"  # no effect: already counting
        gate, _read = self._gate_line_and_reader()  # refuse now if unwired
        est = gate.estimate_edge(self.world.now, self.preset)
        if est is not None and est - self.world.now < MIN_GATE_S:
            dur = est - self.world.now
            least = math.ceil(self.preset * MIN_GATE_S / max(dur, 1e-12))
            raise InstrumentError(25, f"gate of {self.preset} pulses lasts {dur:.3g} s, shorter "
                                      f"than the {PRINT_S:g} s print-out: preset at least {least}")
        self.operating = True
        self.gate_open = None
        self._proc = self.env.process(self._run())
        return "OK"

    def _stby(self, _: list[str]) -> str:
        self._standby("STBY")
        return "OK"

    def _read(self, _: list[str]) -> Deferred | str:
        if self.readings:
            d = Deferred(self.env)
            d.resolve(str(self.readings.popleft()))
            return d
        if not self.operating:
            raise InstrumentError(26, "no reading: counter in standby")
        self._waiters = deque(w for w in self._waiters if not w.cancelled)
        d = Deferred(self.env)
        self._waiters.append(d)
        return d

    def _clr(self, _: list[str]) -> str:
        self.readings.clear()
        return "OK"

    def _refuse_waiters(self, reply: str) -> None:
        """Answer every waiting READ? with an error reply: no reading will come."""
        while self._waiters:
            self._waiters.popleft().resolve(reply)

    def _standby(self, why: str) -> None:
        was = self.operating
        self.operating = False
        self.gate_open = None
        if self._proc is not None and self._proc.is_alive:
            self._proc.interrupt("standby")
        self._proc = None
        if was:
            self._refuse_waiters(f"ERR 26 no reading: counter set to standby by {why}")
