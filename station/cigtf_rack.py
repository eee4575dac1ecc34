"""The simulated CIGTF gyrocompassing station: world, instruments, drivers and clock.

``CigtfRack`` owns the physics and the three serial instruments and registers them as a
VirtualRack for ``sim://NAME``; ``open_cigtf_station`` gives what a procedure sees.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import simpy

from instruments.base import ByteInstrument
from instruments.cigtf import AveragingDvm, FixtureProgrammer, GyroPower
from sim.cigtf_world import CigtfParams, CigtfWorld
from station.clock import VirtualClock
from station.drivers.cigtf import DvmDriver, FixtureDriver, GyroPowerDriver
from station.links import virtual

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
    clock: VirtualClock
    fixture: FixtureDriver
    dvm: DvmDriver
    power: GyroPowerDriver

    def close(self) -> None:
        for d in (self.fixture, self.dvm, self.power):
            d.close()


def open_cigtf_station(rack: CigtfRack, timeout: float = 5.0) -> CigtfStation:
    clock = VirtualClock(rack.env)
    url = {n: f"sim://{n}?rack={rack.rack_id}" for n in rack.serial}
    return CigtfStation(
        clock=clock,
        fixture=FixtureDriver(url["fixture"], clock, timeout=timeout),
        dvm=DvmDriver(url["dvm"], timeout=timeout),
        power=GyroPowerDriver(url["gyro_power"], timeout=timeout),
    )
