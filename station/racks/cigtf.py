"""The simulated CIGTF gyrocompassing station: world, instruments, and the drivers on them.

``CigtfRack`` owns the physics and the three serial instruments; ``open_cigtf_drivers``
gives what a procedure sees: the drivers over the rack's ``sim://`` links on its virtual
clock, or over other links (a rack served with ``station serve --station cigtf``: its ptys)
on a real-time clock.
"""

from __future__ import annotations

from typing import Any

import simpy

from instruments.cigtf import AveragingDvm, FixtureProgrammer, GyroPower, SetupAidsInstrument
from sim.cigtf.world import CigtfParams, CigtfWorld
from station.clock import Clock
from station.drivers.cigtf import (
    CigtfDrivers,
    DvmDriver,
    FixtureDriver,
    GyroPowerDriver,
    SetupAidsDriver,
)
from station.drivers.driver_set import DriverFactory
from station.racks.base import SimRack, open_sim_drivers

LATENCY_S = 0.01
INSTRUMENTS: dict[str, DriverFactory] = {
    "fixture": FixtureDriver, "dvm": DvmDriver, "gyro_power": GyroPowerDriver,
    "setup_aids": SetupAidsDriver}


class CigtfRack(SimRack):
    prefix = "cigtf"

    def __init__(self, seed: int, params: CigtfParams | None = None,
                 env: simpy.Environment | None = None) -> None:
        w = CigtfWorld(seed, params, env)
        self.fixture = FixtureProgrammer("fixture", w, LATENCY_S)
        self.dvm = AveragingDvm("dvm", w, LATENCY_S)
        self.power = GyroPower("gyro_power", w, LATENCY_S)
        self.aids = SetupAidsInstrument("setup_aids", w, LATENCY_S)
        super().__init__(w, {"fixture": self.fixture, "dvm": self.dvm,
                             "gyro_power": self.power, "setup_aids": self.aids})


def open_cigtf_drivers(rack: CigtfRack | None = None, timeout: float = 5.0,
                       links: dict[str, Any] | None = None,
                       clock: Clock | None = None) -> CigtfDrivers:
    """The CIGTF driver set on a local rack or on links (``racks.base.open_sim_drivers``)."""
    drivers: CigtfDrivers = open_sim_drivers(INSTRUMENTS, CigtfDrivers.assemble, "CIGTF", rack,
                                      timeout, links, clock)
    return drivers
