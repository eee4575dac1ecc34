"""Client side of each instrument's protocol: one driver class per instrument, bound by URL."""

from station.drivers.autocollimator import AutocollimatorDriver
from station.drivers.bubble_level import BubbleLevelDriver
from station.drivers.counter import CounterDriver
from station.drivers.ieu import IeuDriver, IeuSample
from station.drivers.oscillator import OscillatorDriver
from station.drivers.patch_panel import PatchPanelDriver
from station.drivers.table import TableDriver

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
