"""The strapdown ISU calibration laboratory (report 000) as the registry sees it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import simpy

from laboratory.registry import Laboratory
from sim.isu.world import World
from station.clock import Clock
from station.config.isu import StationConfig, load_config
from station.drivers.driver_set import Driver
from station.drivers.isu import DRIVERS, IsuDrivers
from station.hil.session import config_digest
from station.racks.base import Rack
from station.racks.isu import SimulatedRack, config_links


def _load(path: Path | None, seed: int | None) -> StationConfig:
    return load_config(path, seed=seed)


def _rack(cfg: StationConfig, env: simpy.Environment | None) -> SimulatedRack:
    return SimulatedRack(cfg, env=env)


def _links(cfg: StationConfig, rack: Rack | None) -> dict[str, Any]:
    return config_links(cfg, rack)  # type: ignore[arg-type]  # an ISU rack's id is all it reads


def shown_links(links: dict[str, Any]) -> dict[str, str]:
    """The links as the record shows them (the IEU as ``interface:channel``)."""
    out = {n: u for n, u in links.items() if n != "ieu"}
    can = links["ieu"]
    out["ieu"] = f"{can['interface']}:{can['channel']}" if isinstance(can, dict) else str(can)
    return out


def _assemble(clock: Clock, opened: dict[str, Driver], links: dict[str, Any]) -> IsuDrivers:
    return IsuDrivers.from_opened(clock, opened, shown_links(links))


def simulated(cfg: StationConfig) -> bool:
    """The config's links reach a simulated rack (sim:// URLs or the sim CAN interface)."""
    return any(u.startswith("sim://") for u in cfg.links.serial.values()) or (
        cfg.links.can.interface == "sim")


def truth(world: World) -> dict[str, float]:
    """The true constants of the Calibration Results Sheet, ``"gyro1.DeltaPhi"`` etc."""
    from laboratory.isu.truth import calibration_truth

    return {f"{inst}.{name}": v for (inst, name), v in calibration_truth(world).items()}


def _commands(app: Any) -> None:
    from laboratory.isu.cli import add_commands

    add_commands(app)


LAB = Laboratory(
    name="isu", title="strapdown ISU calibration laboratory (report 000)",
    config_help="station config TOML (merged over the embedded default)",
    load_config=_load, seed_of=lambda cfg: cfg.seed, digest=config_digest,
    build_rack=_rack, drivers=DRIVERS, links=_links, assemble=_assemble, truth=truth,
    simulated=simulated, add_commands=None,
)
