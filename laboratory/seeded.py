"""Laboratories whose config does not carry the seed and whose instruments are all serial
(CIGTF, ESG): their config is the params and the seed (``Seeded``), and their registry
entry is built the same way from a few parts (``serial_laboratory``)."""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, TypeVar

from laboratory.registry import Laboratory

if TYPE_CHECKING:
    import simpy
    import typer

    from station.clock import Clock
    from station.drivers.driver_set import Driver, DriverFactory
    from station.racks.base import Rack

P = TypeVar("P")
DEFAULT_SEED = 1  # the CIGTF and ESG commands' default seed


@dataclass(frozen=True)
class Seeded(Generic[P]):
    params: P
    seed: int


def seeded(params: P, seed: int | None) -> Seeded[P]:
    return Seeded(params, DEFAULT_SEED if seed is None else int(seed))


@dataclass(frozen=True)
class SerialParts:
    """What differs between two such laboratories (imported when first used)."""

    load_params: Callable[[Path | None], Any]  # --config file -> params (ConfigError)
    rack: Callable[..., Rack]  # rack class: (seed, params, env=...)
    instruments: Mapping[str, DriverFactory]  # instrument -> driver class
    drivers: Any  # the DriverSet subclass (its ``assemble``)


def serial_laboratory(name: str, title: str, config_help: str,
                      parts: Callable[[], SerialParts], truth: Callable[[Any], dict[str, float]],
                      add_commands: Callable[[typer.Typer], None] | None = None) -> Laboratory:
    """The registry entry of a laboratory of serial instruments on a simulated rack: no
    hardware links (its rack is reached locally or served), seed 1 unless given."""
    part = functools.cache(parts)

    def load(path: Path | None, seed: int | None) -> Seeded[Any]:
        return seeded(part().load_params(path), seed)

    def digest(cfg: Seeded[Any]) -> str:
        from station.hil.session import params_digest

        return params_digest(name, cfg.params)

    def rack(cfg: Seeded[Any], env: simpy.Environment | None) -> Rack:
        return part().rack(cfg.seed, cfg.params, env=env)

    def links(cfg: Seeded[Any], rack: Rack | None) -> dict[str, Any]:
        from station.racks.base import sim_links

        if rack is None:
            raise ValueError(f"the {name} laboratory has no hardware links: serve its rack "
                             f"(station serve --station {name}) and use --links")
        return dict(sim_links(part().instruments, rack))

    def assemble(clock: Clock, opened: dict[str, Driver], links: dict[str, Any]) -> Any:
        return part().drivers.assemble(clock, opened)

    return Laboratory(
        name=name, title=title, config_help=config_help, load_config=load,
        seed_of=lambda cfg: cfg.seed, digest=digest, build_rack=rack,
        drivers=lambda: part().instruments, links=links, assemble=assemble, truth=truth,
        add_commands=add_commands)
