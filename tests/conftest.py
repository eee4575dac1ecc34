"""Shared fixtures: the default configuration, a simulated rack and a station bound to it;
the station's own pytest plugin (laboratory/pytest_plugin.py) when the installed package
did not bring it through its ``pytest11`` entry point (a source tree not installed)."""

from __future__ import annotations

import importlib

import pytest

from station.config.isu import load_config
from station.racks.isu import SimulatedRack, open_isu_drivers


@pytest.fixture
def cfg():
    """The embedded default station configuration."""
    return load_config()


@pytest.fixture
def rack(cfg):
    """A simulated rack (world and instruments) built from ``cfg``; unregistered afterwards."""
    r = SimulatedRack(cfg)
    yield r
    r.close()


@pytest.fixture
def station(cfg, rack):
    """Drivers for every instrument of ``rack`` and its virtual clock; closed afterwards."""
    st = open_isu_drivers(cfg, rack)
    yield st
    st.close()


def pytest_configure(config: pytest.Config) -> None:
    """Register the station's plugin under its entry-point name unless already loaded."""
    if not config.pluginmanager.has_plugin("station"):
        config.pluginmanager.register(importlib.import_module("laboratory.pytest_plugin"),
                                      "station")
