"""Bubble levels on the rotary platform (serial): the level corrections for phi1 and phi3.

With the rotary axis up (positions 7-15: phi1 = 0, phi2 = 90 deg) the platform normal R1
should be vertical. Level 1 reads its tilt towards north, which a change of phi1 (about the
east-pointing trunnion axis) removes; level 2 reads its tilt towards east, which a change of
phi3 (about the outer axis R2, along north) removes from everything inside the outer gimbal.
The readings are the corrections to add to phi1 and phi3, in arcsec.

Protocol:  LEV?  -> "<corr_phi1_arcsec> <corr_phi3_arcsec>", or ERR 40 OUT OF RANGE
"""

from __future__ import annotations

import math

from instruments.base import ByteInstrument, InstrumentError
from instruments.isu.params import BubbleLevelParams
from sim import units
from sim.isu.world import World
from sim.rng import stream


class BubbleLevels(ByteInstrument):
    ident = "ISU-LAB,BL-2,0,1.0"

    def __init__(self, name: str, world: World, p: BubbleLevelParams, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.p = p
        self._n = 0
        self.define("LEV?", self._lev)

    def corrections(self) -> tuple[float, float]:
        """True (phi1, phi3) corrections in rad at the present time."""
        f = self.world.table.frames(self.world.now)
        t_re = (f["t_rt"] @ f["t_tf"] @ f["t_fe"])[0]  # rows: R axes in E components
        r1, r2 = t_re[0], t_re[1]
        return float(r1[2]), -float(r1[1]) * math.copysign(1.0, float(r2[2]))

    def _lev(self, _: list[str]) -> str:
        c1, c3 = (units.to_arcsec(c) for c in self.corrections())
        if max(abs(c1), abs(c3)) > self.p.range_arcsec:
            raise InstrumentError(40, "OUT OF RANGE")
        rng = stream(self.world.seed, "bubble", self._n)
        self._n += 1
        q = self.p.resolution_arcsec
        out = [round((c + rng.normal(0, self.p.noise_arcsec)) / q) * q for c in (c1, c3)]
        return f"{out[0]:.2f} {out[1]:.2f}"
