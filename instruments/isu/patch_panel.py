"""Patch panel / switch matrix: routes any pulse line to a counter's X, Y or Z input (Chart II-2).

Protocol (line based, one reply per command):
  CONN <line> <counter> <input>   connect, e.g. CONN G1+ C2 X        -> OK
  DISC <counter> <input>          disconnect                          -> OK
  CONN? <counter> <input>         line on that input, or NONE
  CLR                             disconnect everything               -> OK
  LINES?                          comma-separated list of line names
"""

from __future__ import annotations

from instruments.base import ByteInstrument, InstrumentError
from sim.isu.pulses import PulseLine
from sim.isu.world import World

INPUTS = ("X", "Y", "Z")


class PatchPanel(ByteInstrument):
    ident = "ISU-LAB,PATCH-PANEL,0,1.0"

    def __init__(self, name: str, world: World, n_counters: int, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.counters = tuple(f"C{i}" for i in range(1, n_counters + 1))
        self.conn: dict[tuple[str, str], str] = {}
        self.define("CONN <line> <counter> <input>", self._conn)
        self.define("DISC <counter> <input>", self._disc)
        self.define("CONN? <counter> <input>",
                    lambda a: self.conn.get(self._jack(a[0], a[1]), "NONE"))
        self.define("CLR", self._clr)
        self.define("LINES?", lambda _: ",".join(sorted(self.world.lines)))

    def source(self, counter: str, inp: str) -> PulseLine | None:
        """The pulse line patched to a counter input (used by the counters)."""
        name = self.conn.get((counter, inp))
        return self.world.line(name) if name else None

    def _jack(self, counter: str, inp: str) -> tuple[str, str]:
        c, i = counter.upper(), inp.upper()
        if c not in self.counters:
            raise InstrumentError(
                12, f"no counter '{counter[:20]}' (have {', '.join(self.counters)})")
        if i not in INPUTS:
            raise InstrumentError(12, f"no input '{inp[:20]}' (inputs X, Y, Z)")
        return c, i

    def _conn(self, args: list[str]) -> str:
        line = args[0].upper()
        if line not in self.world.lines:
            raise InstrumentError(12, f"no line '{args[0][:20]}'")
        self.conn[self._jack(args[1], args[2])] = line
        self.world.notify()
        return "OK"

    def _disc(self, args: list[str]) -> str:
        self.conn.pop(self._jack(args[0], args[1]), None)
        self.world.notify()
        return "OK"

    def _clr(self, _: list[str]) -> str:
        self.conn.clear()
        self.world.notify()
        return "OK"
