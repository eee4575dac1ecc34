"""The simulated CIGTF gyrocompassing station: world, instruments, drivers and clock.

``CigtfRack`` owns the physics and the three serial instruments and registers them as a
VirtualRack for ``sim://NAME``; ``open_cigtf_station`` gives what a procedure sees: the
drivers over the rack's ``sim://`` links on its virtual clock, or over other links (a rack
served with ``station serve --station cigtf``: its ptys) on a real-time clock.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import simpy

from instruments.base import ByteInstrument
from instruments.cigtf import AveragingDvm, FixtureProgrammer, GyroPower
from sim.cigtf.world import CigtfParams, CigtfWorld
from station.clock import Clock
from station.drivers.cigtf import DvmDriver, FixtureDriver, GyroPowerDriver
from station.links import virtual
from station.racks.base import open_drivers

_ids = itertools.count(1)
LATENCY_S = 0.01


class CigtfRack:
    def __init__(self, seed: int, params: CigtfParams | None = None,
                 env: simpy.Environment | None = None) -> None:
        self.world = CigtfWorld(seed, params, env)
        self.env = self.world.env
        w = self.world
        self.fixture = FixtureProgrammer("fixture", w, LATENCY_S)
        self.dvm = AveragingDvm("dvm", w, LATENCY_S)
        self.power = GyroPower("gyro_power", w, LATENCY_S)
        self.serial: dict[str, ByteInstrument] = {
            "fixture": self.fixture, "dvm": self.dvm, "gyro_power": self.power}
        self.rack_id = f"cigtf{next(_ids)}"
        virtual.register(virtual.VirtualRack(self.rack_id, self.env, dict(self.serial)))

    def close(self) -> None:
        virtual.unregister(self.rack_id)

    def __enter__(self) -> CigtfRack:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@dataclass
class CigtfStation:
    clock: Clock
    fixture: FixtureDriver
    dvm: DvmDriver
    power: GyroPowerDriver

    def drivers(self) -> list:
        return [self.fixture, self.dvm, self.power]

    def close(self) -> None:
        for d in self.drivers():
            d.close()


def open_cigtf_station(rack: CigtfRack | None = None, timeout: float = 5.0,
                       links: dict[str, str] | None = None,
                       clock: Clock | None = None) -> CigtfStation:
    """Drivers of the fixture, DVM and gyro power supply.

    On ``rack`` (its ``sim://`` links; the clock defaults to its virtual clock), or on
    ``links`` (instrument -> pyserial URL, e.g. the ptys of a served rack) with ``clock``
    (a WallClock on the served rack's time). Every driver takes its link timeouts
    through the clock (``bind_clock``), as in ``open_station``.
    """
    clock, drivers = open_drivers(rack, links, clock, "CIGTF", {
        "fixture": lambda url, clk: FixtureDriver(url, clk, timeout=timeout),
        "dvm": lambda url, clk: DvmDriver(url, timeout=timeout),
        "gyro_power": lambda url, clk: GyroPowerDriver(url, timeout=timeout),
    })
    return CigtfStation(clock, *drivers)
