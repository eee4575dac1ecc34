"""The ESG readout laboratory (report 004) as the registry sees it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import simpy

from laboratory.esg.truth import true_pickoff1_coning_arcsec
from laboratory.registry import Laboratory
from laboratory.seeded import Seeded, seeded
from sim.esg.world import EsgParams, EsgWorld
from station.clock import Clock
from station.config.esg import load_esg_params
from station.drivers.driver_set import Driver
from station.drivers.esg import EsgDrivers
from station.hil.session import params_digest
from station.racks.base import Rack, sim_links
from station.racks.esg import INSTRUMENTS, EsgRack


def _load(path: Path | None, seed: int | None) -> Seeded[EsgParams]:
    return seeded(load_esg_params(path), seed)


def _rack(cfg: Seeded[EsgParams], env: simpy.Environment | None) -> EsgRack:
    return EsgRack(cfg.seed, cfg.params, env=env)


def _links(cfg: Seeded[EsgParams], rack: Rack | None) -> dict[str, Any]:
    if rack is None:
        raise ValueError("the ESG laboratory has no hardware links: serve its rack "
                         "(station serve --station esg) and use --links")
    return dict(sim_links(INSTRUMENTS, rack))


def _assemble(clock: Clock, opened: dict[str, Driver], links: dict[str, Any]) -> EsgDrivers:
    return EsgDrivers.assemble(clock, opened)


def truth(world: EsgWorld) -> dict[str, float]:
    """The static truth an ESG calibration estimates: pickoff 1's coning about the spindle."""
    return {"pickoff1_coning_arcsec": true_pickoff1_coning_arcsec(world)}


LAB = Laboratory(
    name="esg", title="ESG readout laboratory (report 004)",
    config_help="TOML with an [esg] section (site, rotor, [esg.pattern], [esg.signal])",
    load_config=_load, seed_of=lambda cfg: cfg.seed,
    digest=lambda cfg: params_digest("esg", cfg.params),
    build_rack=_rack, drivers=INSTRUMENTS, links=_links, assemble=_assemble, truth=truth,
)
