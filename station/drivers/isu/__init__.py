"""Drivers of the ISU calibration lab's instruments (serial and the IEU on CAN) and their set."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from station.clock import Clock
from station.drivers.driver_set import DriverFactory, DriverSet
from station.drivers.isu.autocollimator import AutocollimatorDriver
from station.drivers.isu.bubble_level import BubbleLevelDriver
from station.drivers.isu.counter import CounterDriver
from station.drivers.isu.ieu import IeuDriver, IeuSample
from station.drivers.isu.oscillator import OscillatorDriver
from station.drivers.isu.patch_panel import PatchPanelDriver
from station.drivers.isu.table import TableDriver

__all__ = [
    "DRIVERS",
    "IsuDrivers",
    "SERIAL_INSTRUMENTS",
    "AutocollimatorDriver",
    "BubbleLevelDriver",
    "CounterDriver",
    "IeuDriver",
    "IeuSample",
    "OscillatorDriver",
    "PatchPanelDriver",
    "TableDriver",
]


@dataclass
class IsuDrivers(DriverSet):
    """What an ISU procedure sees: the drivers of every instrument, and the clock."""

    table: TableDriver
    patch_panel: PatchPanelDriver
    counters: dict[int, CounterDriver]
    autocollimators: dict[int, AutocollimatorDriver]
    bubble_levels: BubbleLevelDriver
    oscillator: OscillatorDriver
    ieu: IeuDriver
    links: dict[str, str] = field(default_factory=dict)  # instrument -> link it was opened on

    @classmethod
    def from_opened(cls, clock: Clock, opened: Mapping[str, Any],
                    links: dict[str, str]) -> IsuDrivers:
        """The set from the drivers opened by instrument name (``DRIVERS``)."""
        return cls(clock, opened["table"], opened["patch_panel"],
                   {i: opened[f"counter{i}"] for i in range(1, MAX_COUNTERS + 1)
                    if f"counter{i}" in opened},
                   {i: opened[f"autocollimator{i}"] for i in (1, 2)},
                   opened["bubble_levels"], opened["oscillator"], opened["ieu"], links)


# instrument name in the rack -> its driver class: the one list of the lab's instruments
DRIVERS: dict[str, DriverFactory] = {
    "table": TableDriver,
    "patch_panel": PatchPanelDriver,
    **{f"counter{i}": CounterDriver for i in range(1, 7)},
    "autocollimator1": AutocollimatorDriver,
    "autocollimator2": AutocollimatorDriver,
    "bubble_levels": BubbleLevelDriver,
    "oscillator": OscillatorDriver,
    "ieu": IeuDriver,
}
SERIAL_INSTRUMENTS = tuple(n for n in DRIVERS if n != "ieu")
# counters beyond report 000's six, when the config's [calibration] counters asks for them
# (II-5: gyro and accelerometer positions measured together); sim:// links only
MAX_COUNTERS = 12
EXTRA_COUNTERS = tuple(f"counter{i}" for i in range(7, MAX_COUNTERS + 1))


def drivers_for(counters: int) -> dict[str, DriverFactory]:
    """``DRIVERS`` with counters 7..``counters`` (6: ``DRIVERS`` itself)."""
    extra = {f"counter{i}": CounterDriver for i in range(7, counters + 1)}
    return {**DRIVERS, **extra} if extra else DRIVERS
