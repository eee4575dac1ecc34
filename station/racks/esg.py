"""The simulated ESG laboratory (report 004): world, instruments, drivers and clock.

``EsgRack`` owns the physics and the five serial instruments (processor, head, turntable,
theodolite, console) and registers them as a VirtualRack for ``sim://NAME``;
``open_esg_station`` gives what a procedure sees: the drivers over the rack's ``sim://``
links on its virtual clock, or over other links (a rack served with ``station serve
--station esg``: its ptys) on a real-time clock.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import simpy

from instruments.base import ByteInstrument
from instruments.esg import DataProcessor, DividingHead, GyroConsole, Theodolite, Turntable
from sim.esg.world import EsgWorld
from station.clock import Clock
from station.drivers.esg import (
    ConsoleDriver,
    HeadDriver,
    ProcessorDriver,
    TheodoliteDriver,
    TurntableDriver,
)
from station.links import virtual
from station.racks.base import open_drivers

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
    clock: Clock
    processor: ProcessorDriver
    head: HeadDriver
    turntable: TurntableDriver
    theodolite: TheodoliteDriver
    console: ConsoleDriver

    def drivers(self) -> list:
        return [self.processor, self.head, self.turntable, self.theodolite, self.console]

    def close(self) -> None:
        for d in self.drivers():
            d.close()


def open_esg_station(rack: EsgRack | None = None, timeout: float = 5.0,
                     links: dict[str, str] | None = None,
                     clock: Clock | None = None) -> EsgStation:
    """Drivers of the five ESG instruments.

    On ``rack`` (its ``sim://`` links; the clock defaults to its virtual clock), or on
    ``links`` (instrument -> pyserial URL, e.g. the ptys of a served rack) with ``clock``
    (a WallClock on the served rack's time). Every driver takes its link timeouts
    through the clock (``bind_clock``), as in ``open_station``.
    """
    clock, drivers = open_drivers(rack, links, clock, "ESG", {
        "processor": lambda url, clk: ProcessorDriver(url, timeout=timeout),
        "head": lambda url, clk: HeadDriver(url, clk, timeout=timeout),
        "turntable": lambda url, clk: TurntableDriver(url, clk, timeout=timeout),
        "theodolite": lambda url, clk: TheodoliteDriver(url, timeout=timeout),
        "console": lambda url, clk: ConsoleDriver(url, timeout=timeout),
    })
    return EsgStation(clock, *drivers)
