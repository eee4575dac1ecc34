"""The ESG readout laboratory (report 004) as the registry sees it.

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

    from sim.esg.world import EsgParams, EsgWorld
    from station.clock import Clock
    from station.drivers.driver_set import Driver, DriverFactory
    from station.drivers.esg import EsgDrivers
    from station.racks.base import Rack
    from station.racks.esg import EsgRack


def _load(path: Path | None, seed: int | None) -> Seeded[EsgParams]:
    from station.config.esg import load_esg_params

    return seeded(load_esg_params(path), seed)


def _digest(cfg: Seeded[EsgParams]) -> str:
    from station.hil.session import params_digest

    return params_digest("esg", cfg.params)


def _rack(cfg: Seeded[EsgParams], env: simpy.Environment | None) -> EsgRack:
    from station.racks.esg import EsgRack

    return EsgRack(cfg.seed, cfg.params, env=env)


def _drivers() -> dict[str, DriverFactory]:
    from station.racks.esg import INSTRUMENTS

    return INSTRUMENTS


def _links(cfg: Seeded[EsgParams], rack: Rack | None) -> dict[str, Any]:
    from station.racks.base import sim_links

    if rack is None:
        raise ValueError("the ESG laboratory has no hardware links: serve its rack "
                         "(station serve --station esg) and use --links")
    return dict(sim_links(_drivers(), rack))


def _assemble(clock: Clock, opened: dict[str, Driver], links: dict[str, Any]) -> EsgDrivers:
    from station.drivers.esg import EsgDrivers

    return EsgDrivers.assemble(clock, opened)


def truth(world: EsgWorld) -> dict[str, float]:
    """The static truth an ESG calibration estimates: pickoff 1's coning about the spindle."""
    from laboratory.esg.truth import true_pickoff1_coning_arcsec

    return {"pickoff1_coning_arcsec": true_pickoff1_coning_arcsec(world)}


def _commands(app: typer.Typer) -> None:
    from laboratory.esg.cli import add_commands

    add_commands(app)


LAB = Laboratory(
    name="esg", title="ESG readout laboratory (report 004)",
    config_help="TOML with an [esg] section (site, rotor, [esg.pattern], [esg.signal])",
    load_config=_load, seed_of=lambda cfg: cfg.seed, digest=_digest,
    build_rack=_rack, drivers=_drivers, links=_links, assemble=_assemble, truth=truth,
    add_commands=_commands,
)
