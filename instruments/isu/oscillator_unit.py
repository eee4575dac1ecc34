"""Master oscillator front panel (serial): status, countdown settings, self-test.

Protocol: FREQ? (nominal Hz), DIV? <1|2> (countdown ratio of S1^T / S2^T), STAT? (LOCKED),
TEST? (PASS).
"""

from __future__ import annotations

from instruments.base import ByteInstrument, as_int
from sim.isu.world import World


class OscillatorUnit(ByteInstrument):
    ident = "ISU-LAB,MO-5M,0,1.0"

    def __init__(self, name: str, world: World, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.osc = world.oscillator
        self.define("FREQ?", lambda _: f"{self.osc.p.nominal_hz:.1f}")
        self.define("DIV? <1|2>", self._div)
        self.define("STAT?", lambda _: "LOCKED")
        self.define("TEST?", lambda _: "PASS")

    def _div(self, args: list[str]) -> str:
        k = as_int(args[0], "output", 1, 2)
        return str(self.osc.p.s1_divider if k == 1 else self.osc.p.s2_divider)
