"""The toy laboratory's driver, driver set and rack (the station floor's three parts)."""

from __future__ import annotations

from dataclasses import dataclass

import simpy

from station.drivers.driver_set import DriverSet
from station.drivers.replies import Form, fixed
from station.drivers.serial_base import SerialDriver
from station.racks.base import SimRack
from toylab.thermometer import Thermometer
from toylab.world import BathWorld, ToyParams

TEMPERATURE = Form([fixed("temperature, K", 4, 0.0, 1000.0)])


class ThermometerDriver(SerialDriver):
    model = ("TOY-LAB", "THERMOMETER")

    def temperature_k(self) -> float:
        return self.ask("TEMP?", TEMPERATURE)[0]


@dataclass
class ToyDrivers(DriverSet):
    thermometer: ThermometerDriver


class ToyRack(SimRack):
    prefix = "toy"

    def __init__(self, seed: int, params: ToyParams | None = None,
                 env: simpy.Environment | None = None) -> None:
        w = BathWorld(seed, params, env)
        super().__init__(w, {"thermometer": Thermometer("thermometer", w, 0.01)})
