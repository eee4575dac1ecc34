"""The laboratories the station knows: one table, each entry declared in its own package.

A laboratory is a ``Laboratory``: its name (``--station NAME``, the served session's
station), its config (how to read it from a file, its seed, the digest a served session
publishes), how to build its simulated rack, how to open its drivers and clock (on a local
rack in virtual time, on a served rack's links in real time, or on the configured links of
the hardware), its truth, and its commands (the procedures' entry points on the command
line). The CLI, ``station serve``, ``station check`` and the connection code reach a
laboratory only through this table.

Entries are ``"module:attribute"`` strings, imported when first asked for; a declaration
imports nothing heavy itself (its callables import what they use), so that listing the
laboratories and their commands costs milliseconds and a command pays only for its own
laboratory. Laboratories kept outside this package are
added by the ``station.laboratories`` entry-point group of an installed distribution, or
by the environment variable ``STATION_LABORATORIES`` (``name=module:attribute``, comma
separated), read when the table is first used.
"""

from __future__ import annotations

import functools
import importlib
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import TYPE_CHECKING, Any

from station.errors import UseError

if TYPE_CHECKING:
    import simpy
    import typer

    from station.clock import Clock
    from station.drivers.driver_set import Driver, DriverFactory, DriverSet
    from station.racks.base import Rack

BUILTIN = {
    "isu": "laboratory.isu.lab:LAB",
    "cigtf": "laboratory.cigtf.lab:LAB",
    "esg": "laboratory.esg.lab:LAB",
}
ENV_VAR = "STATION_LABORATORIES"
ENTRY_POINTS = "station.laboratories"


@dataclass(frozen=True)
class Laboratory:
    """One laboratory as the application reaches it (see the module doc)."""

    name: str
    title: str
    config_help: str  # what --config holds for it (the whole file, or its section)
    load_config: Callable[[Path | None, int | None], Any]  # (file, --seed): its config
    seed_of: Callable[[Any], int]  # the run's seed given its loaded config
    digest: Callable[[Any], str]  # of the config: a served session publishes it
    build_rack: Callable[[Any, simpy.Environment | None], Rack]  # on its own env if None
    drivers: Callable[[], Mapping[str, DriverFactory]]  # instrument -> driver class
    links: Callable[[Any, Rack | None], dict[str, Any]]  # local rack's, or configured
    assemble: Callable[[Clock, dict[str, Driver], dict[str, Any]], DriverSet]
    truth: Callable[[Any], dict[str, float]]  # the world's true values a run estimates
    simulated: Callable[[Any], bool] = lambda cfg: True  # False: its links reach hardware
    add_commands: Callable[[typer.Typer], None] | None = None  # its procedures' commands


class UnknownLaboratory(UseError, ValueError):
    """A --station name (or a registry entry) that names no laboratory."""


@functools.cache
def _installed() -> tuple[tuple[str, str], ...]:
    """The installed packages' laboratories (entry points): read once per process, since
    scanning every distribution's metadata costs tens of ms and the CLI asks four times."""
    return tuple((ep.name, ep.value) for ep in entry_points(group=ENTRY_POINTS))


def _entries(installed: bool = True) -> dict[str, str]:
    """Every laboratory's entry: the built-in ones, then the installed ones (``installed``;
    they cannot take a built-in name), then $STATION_LABORATORIES (which can)."""
    table = dict(BUILTIN)
    for name, value in _installed() if installed else ():
        table.setdefault(name, value)
    for item in filter(None, (x.strip() for x in os.environ.get(ENV_VAR, "").split(","))):
        name, sep, target = item.partition("=")
        if not sep or ":" not in target or not name.strip():
            raise UnknownLaboratory(f"{ENV_VAR}: {item!r} is not name=module:attribute")
        table[name.strip()] = target.strip()
    return table


def names(installed: bool = True) -> list[str]:
    """The names of every laboratory known (built in first); without ``installed``, only
    the built-in and $STATION_LABORATORIES ones (no scan of the installed packages)."""
    return list(_entries(installed))


_loaded: dict[str, Laboratory] = {}


def get(name: str) -> Laboratory:
    """The laboratory called ``name``; UnknownLaboratory naming the ones known."""
    if name in _loaded:
        return _loaded[name]
    # a built-in name is never an installed package's (``_entries``): no scan for it
    table = _entries(installed=name not in BUILTIN)
    if name not in table:
        raise UnknownLaboratory(f"--station: unknown laboratory {name!r} (known: "
                                f"{', '.join(table)})")
    module, _, attr = table[name].partition(":")
    try:
        lab = getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as e:
        raise UnknownLaboratory(f"laboratory {name!r}: cannot load {table[name]} ({e})") from None
    if not isinstance(lab, Laboratory) or lab.name != name:
        raise UnknownLaboratory(f"laboratory {name!r}: {table[name]} is not a Laboratory "
                                f"named {name!r}")
    _loaded[name] = lab
    return lab
