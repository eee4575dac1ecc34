"""Builds the simulated ISU laboratory (world + instruments) and the drivers that reach it.

``SimulatedRack`` owns the physics and the virtual instruments and registers them for the
``sim://`` serial handler and the ``sim`` CAN interface. ``Station`` is what a procedure
receives: drivers bound to the configured links, and the clock. Nothing else.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

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
from station.drivers.isu import (
    AutocollimatorDriver,
    BubbleLevelDriver,
    CounterDriver,
    IeuDriver,
    OscillatorDriver,
    PatchPanelDriver,
    TableDriver,
)
from station.links import virtual

_ids = itertools.count(1)


class SimulatedRack:
    """The world and every instrument of the ISU laboratory on one simpy environment."""

    def __init__(self, cfg: StationConfig, env: simpy.Environment | None = None) -> None:
        self.cfg = cfg
        self.world = World(cfg.world_params(), cfg.seed, env)
        self.env = self.world.env
        ip = cfg.instruments
        lat = ip.serial.latency_s
        w = self.world
        panel = PatchPanel("patch_panel", w, 6, lat)
        self.serial: dict[str, ByteInstrument] = {
            "table": TableController("table", w, lat),
            "patch_panel": panel,
        }
        for i in range(1, 7):
            self.serial[f"counter{i}"] = FrequencyCounter(f"counter{i}", f"C{i}", w, panel, lat)
        for i in (1, 2):
            self.serial[f"autocollimator{i}"] = Autocollimator(
                f"autocollimator{i}", i, w, ip.autocollimator, lat
            )
        self.serial["bubble_levels"] = BubbleLevels("bubble_levels", w, ip.bubble_level, lat)
        self.serial["oscillator"] = OscillatorUnit("oscillator", w, lat)
        self.ieu = Ieu("ieu", w, ip.ieu)
        self.rack_id = f"rack{next(_ids)}"
        virtual.register(
            virtual.VirtualRack(self.rack_id, self.env, dict(self.serial), {"ieu": self.ieu})
        )
        apply_faults(self.serial, self.ieu, cfg.faults, cfg.seed)

    def close(self) -> None:
        virtual.unregister(self.rack_id)

    def __enter__(self) -> SimulatedRack:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _bind(url: str, rack_id: str | None) -> str:
    """Pin a sim:// URL to a particular rack (several racks may live in one process)."""
    if rack_id and url.startswith("sim://") and "rack=" not in url:
        return f"{url}{'&' if '?' in url else '?'}rack={rack_id}"
    return url


def can_config(cfg: StationConfig, rack_id: str | None) -> dict:
    """The IEU's python-can configuration, pinned to a rack for the ``sim`` interface."""
    can_cfg = cfg.links.can.model_dump()
    if rack_id and can_cfg.get("interface") == "sim":
        can_cfg["rack"] = rack_id
    return can_cfg


@dataclass
class Station:
    """What a procedure sees: drivers and the clock."""

    clock: Clock
    table: TableDriver
    patch_panel: PatchPanelDriver
    counters: dict[int, CounterDriver]
    autocollimators: dict[int, AutocollimatorDriver]
    bubble_levels: BubbleLevelDriver
    oscillator: OscillatorDriver
    ieu: IeuDriver
    links: dict[str, str] = field(default_factory=dict)

    def drivers(self) -> list:
        return [self.table, self.patch_panel, self.bubble_levels, self.oscillator,
                *self.counters.values(), *self.autocollimators.values(), self.ieu]

    def close(self) -> None:
        for d in self.drivers():
            d.close()


def open_station(
    cfg: StationConfig,
    rack: SimulatedRack | None = None,
    clock: Clock | None = None,
    timeout: float = 5.0,
) -> Station:
    """Drivers for every instrument over the configured links (pinned to ``rack`` if given)."""
    rid = rack.rack_id if rack else None
    if clock is None:
        clock = VirtualClock(rack.env) if rack else WallClock()
    links = {n: _bind(u, rid) for n, u in cfg.links.serial.items()}
    can_cfg = can_config(cfg, rid)
    links["ieu"] = f"{can_cfg['interface']}:{can_cfg['channel']}"
    st = Station(
        clock=clock,
        table=TableDriver(links["table"], clock, timeout=timeout),
        patch_panel=PatchPanelDriver("patch_panel", links["patch_panel"], timeout),
        counters={
            i: CounterDriver(f"counter{i}", links[f"counter{i}"], timeout) for i in range(1, 7)
        },
        autocollimators={
            i: AutocollimatorDriver(f"autocollimator{i}", links[f"autocollimator{i}"], timeout)
            for i in (1, 2)
        },
        bubble_levels=BubbleLevelDriver("bubble_levels", links["bubble_levels"], timeout),
        oscillator=OscillatorDriver("oscillator", links["oscillator"], timeout),
        ieu=IeuDriver(can_cfg, timeout=timeout),
        links=links,
    )
    for d in st.drivers():
        d.bind_clock(clock)
    return st
