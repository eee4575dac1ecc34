"""Builds the simulated ISU laboratory (world + instruments) and the drivers that reach it.

``SimulatedRack`` owns the physics and the virtual instruments and registers them for the
``sim://`` serial handler and the ``sim`` CAN interface. ``open_isu_drivers`` gives what a
procedure receives (``IsuDrivers``): drivers bound to the configured links, and the clock.
"""

from __future__ import annotations

from typing import Any

import simpy

from instruments.base import ByteInstrument
from instruments.faults import apply_faults
from instruments.isu.autocollimator import Autocollimator
from instruments.isu.bubble_level import BubbleLevels
from instruments.isu.counter import FrequencyCounter
from instruments.isu.ieu import Ieu
from instruments.isu.oscillator_unit import OscillatorUnit
from instruments.isu.patch_panel import PatchPanel
from instruments.isu.table_controller import TableController
from sim.isu.world import World
from station.clock import Clock, VirtualClock, WallClock
from station.config.isu import StationConfig
from station.drivers.isu import IsuDrivers, drivers_for
from station.racks.base import Rack, SimRack, open_drivers, pin


class SimulatedRack(SimRack):
    """The world and every instrument of the ISU laboratory on one simpy environment."""

    prefix = "rack"

    def __init__(self, cfg: StationConfig, env: simpy.Environment | None = None) -> None:
        self.cfg = cfg
        w = World(cfg.world_params(), cfg.seed, env)
        ip = cfg.instruments
        lat = ip.serial.latency_s
        n_counters = rack_counters(cfg)
        panel = PatchPanel("patch_panel", w, n_counters, lat)
        serial: dict[str, ByteInstrument] = {
            "table": TableController("table", w, lat),
            "patch_panel": panel,
        }
        for i in range(1, n_counters + 1):
            serial[f"counter{i}"] = FrequencyCounter(f"counter{i}", f"C{i}", w, panel, lat)
        for i in (1, 2):
            serial[f"autocollimator{i}"] = Autocollimator(
                f"autocollimator{i}", i, w, ip.autocollimator, lat
            )
        serial["bubble_levels"] = BubbleLevels("bubble_levels", w, ip.bubble_level, lat)
        serial["oscillator"] = OscillatorUnit("oscillator", w, lat)
        self.ieu = Ieu("ieu", w, ip.ieu)
        super().__init__(w, serial, {"ieu": self.ieu})
        apply_faults(self.serial, self.ieu, cfg.faults, cfg.seed)


def rack_counters(cfg: StationConfig) -> int:
    """The rack's frequency counters: six, or the config's ``[calibration] counters``."""
    return 6 if cfg.calibration is None else cfg.calibration.counters


def can_config(cfg: StationConfig, rack_id: str | None) -> dict:
    """The IEU's python-can configuration, pinned to a rack for the ``sim`` interface."""
    can_cfg = cfg.links.can.model_dump()
    if rack_id and can_cfg.get("interface") == "sim":
        can_cfg["rack"] = rack_id
    return can_cfg


def config_links(cfg: StationConfig, rack: Rack | None = None) -> dict[str, Any]:
    """Each instrument's link from the config (pinned to ``rack`` if given): a pyserial URL,
    and python-can's bus configuration for the IEU."""
    rid = rack.rack_id if rack else None
    links: dict[str, Any] = {n: pin(u, rid) for n, u in cfg.links.serial.items()}
    simulated = all(u.startswith("sim://") for u in cfg.links.serial.values())
    for i in range(7, rack_counters(cfg) + 1):  # counters the [calibration] table adds
        name = f"counter{i}"
        if name not in links:  # never given: [links.serial] refuses it
            if not simulated:  # [links.serial] names report 000's six counters only
                raise ValueError(f"[calibration] counters = {rack_counters(cfg)}: counters "
                                 "beyond six exist on a simulated rack only (no link for "
                                 f"{name} in [links.serial])")
            links[name] = pin(f"sim://{name}", rid)
    links["ieu"] = can_config(cfg, rid)
    return links


def open_isu_drivers(
    cfg: StationConfig,
    rack: SimulatedRack | None = None,
    clock: Clock | None = None,
    timeout: float = 5.0,
) -> IsuDrivers:
    """Drivers for every instrument over the configured links (pinned to ``rack`` if given)."""
    if clock is None:
        clock = VirtualClock(rack.env) if rack else WallClock()
    links = config_links(cfg, rack)
    opened = open_drivers(drivers_for(rack_counters(cfg)), links, clock, timeout)
    shown = {n: u for n, u in links.items() if n != "ieu"}
    shown["ieu"] = f"{links['ieu']['interface']}:{links['ieu']['channel']}"
    return IsuDrivers.from_opened(clock, opened, shown)
