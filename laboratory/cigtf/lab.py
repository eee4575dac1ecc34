"""The CIGTF gyrocompassing test (report 001) as the registry sees it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import simpy

from laboratory.registry import Laboratory
from laboratory.seeded import Seeded, seeded
from sim.cigtf.world import CigtfParams, CigtfWorld
from station.clock import Clock
from station.config.cigtf import load_cigtf_params
from station.drivers.cigtf import CigtfDrivers
from station.drivers.driver_set import Driver
from station.hil.session import params_digest
from station.racks.base import Rack, sim_links
from station.racks.cigtf import INSTRUMENTS, CigtfRack


def _load(path: Path | None, seed: int | None) -> Seeded[CigtfParams]:
    return seeded(load_cigtf_params(path), seed)


def _rack(cfg: Seeded[CigtfParams], env: simpy.Environment | None) -> CigtfRack:
    return CigtfRack(cfg.seed, cfg.params, env=env)


def _links(cfg: Seeded[CigtfParams], rack: Rack | None) -> dict[str, Any]:
    if rack is None:
        raise ValueError("the CIGTF station has no hardware links: serve its rack "
                         "(station serve --station cigtf) and use --links")
    return dict(sim_links(INSTRUMENTS, rack))


def _assemble(clock: Clock, opened: dict[str, Driver], links: dict[str, Any]) -> CigtfDrivers:
    return CigtfDrivers.assemble(clock, opened)


def truth(world: CigtfWorld) -> dict[str, float]:
    """The fixture's true azimuth error the test measures (theta, arcsec)."""
    return {"theta_arcsec": world.truth_theta_arcsec()}


LAB = Laboratory(
    name="cigtf", title="CIGTF gyrocompassing test (report 001)",
    config_help="TOML with a [cigtf] section (site, gyro model, fixture)",
    load_config=_load, seed_of=lambda cfg: cfg.seed,
    digest=lambda cfg: params_digest("cigtf", cfg.params),
    build_rack=_rack, drivers=INSTRUMENTS, links=_links, assemble=_assemble, truth=truth,
)
