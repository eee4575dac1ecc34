"""The simulated ESG laboratory (report 004): world, instruments, drivers and clock.

``EsgRack`` owns the physics and the five serial instruments (processor, head, turntable,
theodolite, console) and registers them as a VirtualRack for ``sim://NAME``;
``open_esg_station`` gives what a procedure sees.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import simpy

from instruments.base import ByteInstrument
from instruments.esg import DataProcessor, DividingHead, GyroConsole, Theodolite, Turntable
from sim.esg.world import EsgWorld
from station.clock import VirtualClock
from station.drivers.esg import (
    ConsoleDriver,
    HeadDriver,
    ProcessorDriver,
    TheodoliteDriver,
    TurntableDriver,
)
from station.links import virtual

_ids = itertools.count(1)
LATENCY_S = 0.01


class EsgRack:
    def __init__(self, seed: int, params=None, env: simpy.Environment | None = None) -> None:
        self.world = EsgWorld(seed, params, env)
        self.env = self.world.env
        w = self.world
        self.processor = DataProcessor("processor", w, LATENCY_S)
        self.head = DividingHead("head", w, LATENCY_S)
        self.turntable = Turntable("turntable", w, LATENCY_S)
        self.theodolite = Theodolite("theodolite", w, LATENCY_S)
        self.console = GyroConsole("console", w, LATENCY_S)
        self.serial: dict[str, ByteInstrument] = {
            "processor": self.processor, "head": self.head, "turntable": self.turntable,
            "theodolite": self.theodolite, "console": self.console}
        self.rack_id = f"esg{next(_ids)}"
        virtual.register(virtual.VirtualRack(self.rack_id, self.env, dict(self.serial)))

    def close(self) -> None:
        virtual.unregister(self.rack_id)

    def __enter__(self) -> EsgRack:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@dataclass
class EsgStation:
    clock: VirtualClock
    processor: ProcessorDriver
    head: HeadDriver
    turntable: TurntableDriver
    theodolite: TheodoliteDriver
    console: ConsoleDriver

    def close(self) -> None:
        for d in (self.processor, self.head, self.turntable, self.theodolite, self.console):
            d.close()


def open_esg_station(rack: EsgRack, timeout: float = 5.0) -> EsgStation:
    clock = VirtualClock(rack.env)
    url = {n: f"sim://{n}?rack={rack.rack_id}" for n in rack.serial}
    return EsgStation(
        clock=clock,
        processor=ProcessorDriver(url["processor"], timeout=timeout),
        head=HeadDriver(url["head"], clock, timeout=timeout),
        turntable=TurntableDriver(url["turntable"], clock, timeout=timeout),
        theodolite=TheodoliteDriver(url["theodolite"], timeout=timeout),
        console=ConsoleDriver(url["console"], timeout=timeout),
    )
