"""Drivers of the ISU calibration lab's instruments (serial and the IEU on CAN)."""

from station.drivers.isu.autocollimator import AutocollimatorDriver
from station.drivers.isu.bubble_level import BubbleLevelDriver
from station.drivers.isu.counter import CounterDriver
from station.drivers.isu.ieu import IeuDriver, IeuSample
from station.drivers.isu.oscillator import OscillatorDriver
from station.drivers.isu.patch_panel import PatchPanelDriver
from station.drivers.isu.table import TableDriver

__all__ = [
    "AutocollimatorDriver",
    "BubbleLevelDriver",
    "CounterDriver",
    "IeuDriver",
    "IeuSample",
    "OscillatorDriver",
    "PatchPanelDriver",
    "TableDriver",
]
