"""The simulated ESG laboratory (report 004): world, instruments, and the drivers on them.

``EsgRack`` owns the physics and the five serial instruments (processor, head, turntable,
theodolite, console); ``open_esg_drivers`` gives what a procedure sees: the drivers over
the rack's ``sim://`` links on its virtual clock, or over other links (a rack served with
``station serve --station esg``: its ptys) on a real-time clock.
"""

from __future__ import annotations

from typing import Any

import simpy

from instruments.esg import DataProcessor, DividingHead, GyroConsole, Theodolite, Turntable
from sim.esg.world import EsgParams, EsgWorld
from station.clock import Clock
from station.drivers.driver_set import DriverFactory
from station.drivers.esg import (
    ConsoleDriver,
    EsgDrivers,
    HeadDriver,
    ProcessorDriver,
    TheodoliteDriver,
    TurntableDriver,
)
from station.racks.base import SimRack, open_sim_drivers

LATENCY_S = 0.01
INSTRUMENTS: dict[str, DriverFactory] = {
    "processor": ProcessorDriver, "head": HeadDriver, "turntable": TurntableDriver,
    "theodolite": TheodoliteDriver, "console": ConsoleDriver}


class EsgRack(SimRack):
    prefix = "esg"

    def __init__(self, seed: int, params: EsgParams | None = None,
                 env: simpy.Environment | None = None) -> None:
        w = EsgWorld(seed, params, env)
        self.processor = DataProcessor("processor", w, LATENCY_S)
        self.head = DividingHead("head", w, LATENCY_S)
        self.turntable = Turntable("turntable", w, LATENCY_S)
        self.theodolite = Theodolite("theodolite", w, LATENCY_S)
        self.console = GyroConsole("console", w, LATENCY_S)
        super().__init__(w, {"processor": self.processor, "head": self.head,
                             "turntable": self.turntable, "theodolite": self.theodolite,
                             "console": self.console})


def open_esg_drivers(rack: EsgRack | None = None, timeout: float = 5.0,
                     links: dict[str, Any] | None = None,
                     clock: Clock | None = None) -> EsgDrivers:
    """The ESG driver set on a local rack or on links (``racks.base.open_sim_drivers``)."""
    drivers: EsgDrivers = open_sim_drivers(INSTRUMENTS, EsgDrivers.assemble, "ESG", rack,
                                      timeout, links, clock)
    return drivers
