"""The strapdown ISU calibration laboratory (report 000) as the registry sees it.

Nothing heavy is imported here (the registry's rule): each callable imports what it uses.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from laboratory.registry import Laboratory

if TYPE_CHECKING:
    import simpy
    import typer

    from sim.isu.world import World
    from station.clock import Clock
    from station.config.isu import StationConfig
    from station.drivers.driver_set import Driver, DriverFactory
    from station.drivers.isu import IsuDrivers
    from station.racks.base import Rack
    from station.racks.isu import SimulatedRack


def _load(path: Path | None, seed: int | None) -> StationConfig:
    from station.config.isu import load_config

    return load_config(path, seed=seed)


def _digest(cfg: StationConfig) -> str:
    from station.hil.session import config_digest

    return config_digest(cfg)


def _rack(cfg: StationConfig, env: simpy.Environment | None) -> SimulatedRack:
    from station.racks.isu import SimulatedRack

    return SimulatedRack(cfg, env=env)


def _drivers() -> dict[str, DriverFactory]:
    from station.drivers.isu import DRIVERS

    return DRIVERS


def _links(cfg: StationConfig, rack: Rack | None) -> dict[str, Any]:
    from station.racks.isu import config_links

    return config_links(cfg, rack)


def shown_links(links: dict[str, Any]) -> dict[str, str]:
    """The links as the record shows them (the IEU as ``interface:channel``)."""
    out = {n: u for n, u in links.items() if n != "ieu"}
    can = links["ieu"]
    out["ieu"] = f"{can['interface']}:{can['channel']}" if isinstance(can, dict) else str(can)
    return out


def _assemble(clock: Clock, opened: dict[str, Driver], links: dict[str, Any]) -> IsuDrivers:
    """The driver set; counters beyond the six (``[calibration] counters``, whose links
    ``config_links`` adds) are opened here, the registry's list being report 000's rack."""
    from station.drivers.isu import EXTRA_COUNTERS, IsuDrivers
    from station.drivers.isu.counter import CounterDriver

    extra = {n: CounterDriver(n, links[n], clock) for n in EXTRA_COUNTERS
             if n in links and n not in opened}
    return IsuDrivers.from_opened(clock, {**opened, **extra}, shown_links(links))


def simulated(cfg: StationConfig) -> bool:
    """The config's links reach a simulated rack (sim:// URLs or the sim CAN interface)."""
    return any(u.startswith("sim://") for u in cfg.links.serial.values()) or (
        cfg.links.can.interface == "sim")


def truth(world: World) -> dict[str, float]:
    """The true constants of the Calibration Results Sheet, ``"gyro1.DeltaPhi"`` etc."""
    from laboratory.isu.truth import calibration_truth

    return {f"{inst}.{name}": v for (inst, name), v in calibration_truth(world).items()}


def _commands(app: typer.Typer) -> None:
    from laboratory.isu.cli import add_commands

    add_commands(app)


LAB = Laboratory(
    name="isu", title="strapdown ISU calibration laboratory (report 000)",
    config_help="station config TOML (merged over the embedded default)",
    load_config=_load, seed_of=lambda cfg: cfg.seed, digest=_digest,
    build_rack=_rack, drivers=_drivers, links=_links, assemble=_assemble, truth=truth,
    simulated=simulated,
    add_commands=_commands,
)
