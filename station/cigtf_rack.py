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
from sim.cigtf_world import CigtfParams, CigtfWorld
from station.clock import Clock, VirtualClock
from station.drivers.cigtf import DvmDriver, FixtureDriver, GyroPowerDriver
from station.links import virtual

_ids = itertools.count(1)
LATENCY_S = 0.01
INSTRUMENTS = ("fixture", "dvm", "gyro_power")


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


def station_links(names, rack_id: str | None, links: dict[str, str] | None,
                  what: str) -> dict[str, str]:
    """URL per instrument: ``sim://NAME?rack=ID`` of a local rack, or the given ``links``."""
    if links is None:
        if rack_id is None:
            raise ValueError(f"open the {what} station on a rack or on links")
        return {n: f"sim://{n}?rack={rack_id}" for n in names}
    missing = [n for n in names if n not in links]
    if missing:
        raise ValueError(f"no link for the {what} instrument(s) {', '.join(missing)} "
                         f"(links for: {', '.join(sorted(links)) or 'none'})")
    return dict(links)


def open_cigtf_station(rack: CigtfRack | None = None, timeout: float = 5.0,
                       links: dict[str, str] | None = None,
                       clock: Clock | None = None) -> CigtfStation:
    """Drivers of the fixture, DVM and gyro power supply.

    On ``rack`` (its ``sim://`` links; the clock defaults to its virtual clock), or on
    ``links`` (instrument -> pyserial URL, e.g. the ptys of a served rack) with ``clock``
    (a WallClock on the served rack's time). Every driver takes its link timeouts
    through the clock (``bind_clock``), as in ``open_station``.
    """
    url = station_links(INSTRUMENTS, rack.rack_id if rack else None, links, "CIGTF")
    if clock is None:
        if rack is None:
            raise ValueError("a CIGTF station on links needs its clock")
        clock = VirtualClock(rack.env)
    opened: list = []
    try:
        opened.append(FixtureDriver(url["fixture"], clock, timeout=timeout))
        opened.append(DvmDriver(url["dvm"], timeout=timeout))
        opened.append(GyroPowerDriver(url["gyro_power"], timeout=timeout))
    except BaseException:
        for d in opened:
            d.close()
        raise
    st = CigtfStation(clock, *opened)
    for d in st.drivers():
        d.bind_clock(clock)
    return st
