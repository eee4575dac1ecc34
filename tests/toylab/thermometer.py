"""The toy laboratory's one instrument: a serial thermometer (``TEMP?`` in kelvin)."""

from __future__ import annotations

from instruments.base import ByteInstrument
from toylab.world import BathWorld


class Thermometer(ByteInstrument):
    ident = "TOY-LAB,THERMOMETER,0,1.0"

    def __init__(self, name: str, world: BathWorld, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.define("TEMP?", lambda _: f"{world.reading_k():.4f}")
