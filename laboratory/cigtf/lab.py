"""The CIGTF gyrocompassing test (report 001) as the registry sees it.

Nothing heavy is imported here (the registry's rule): each callable imports what it uses.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from laboratory.registry import Laboratory
from laboratory.seeded import Seeded, seeded

if TYPE_CHECKING:
    import simpy
    import typer

    from sim.cigtf.world import CigtfParams, CigtfWorld
    from station.clock import Clock
    from station.drivers.cigtf import CigtfDrivers
    from station.drivers.driver_set import Driver, DriverFactory
    from station.racks.base import Rack
    from station.racks.cigtf import CigtfRack


def _load(path: Path | None, seed: int | None) -> Seeded[CigtfParams]:
    from station.config.cigtf import load_cigtf_params

    return seeded(load_cigtf_params(path), seed)


def _digest(cfg: Seeded[CigtfParams]) -> str:
    from station.hil.session import params_digest

    return params_digest("cigtf", cfg.params)


def _rack(cfg: Seeded[CigtfParams], env: simpy.Environment | None) -> CigtfRack:
    from station.racks.cigtf import CigtfRack

    return CigtfRack(cfg.seed, cfg.params, env=env)


def _drivers() -> dict[str, DriverFactory]:
    from station.racks.cigtf import INSTRUMENTS

    return INSTRUMENTS


def _links(cfg: Seeded[CigtfParams], rack: Rack | None) -> dict[str, Any]:
    from station.racks.base import sim_links

    if rack is None:
        raise ValueError("the CIGTF station has no hardware links: serve its rack "
                         "(station serve --station cigtf) and use --links")
    return dict(sim_links(_drivers(), rack))


def _assemble(clock: Clock, opened: dict[str, Driver], links: dict[str, Any]) -> CigtfDrivers:
    from station.drivers.cigtf import CigtfDrivers

    return CigtfDrivers.assemble(clock, opened)


def truth(world: CigtfWorld) -> dict[str, float]:
    """The fixture's true azimuth error the test measures (eq. 26, theta, arcsec)."""
    return {"theta_arcsec": world.truth_theta_arcsec()}


def _commands(app: typer.Typer) -> None:
    from laboratory.cigtf.cli import add_commands

    add_commands(app)


LAB = Laboratory(
    name="cigtf", title="CIGTF gyrocompassing test (report 001)",
    config_help="TOML with a [cigtf] section (site, gyro model, fixture)",
    load_config=_load, seed_of=lambda cfg: cfg.seed, digest=_digest,
    build_rack=_rack, drivers=_drivers, links=_links, assemble=_assemble, truth=truth,
    add_commands=_commands,
)
