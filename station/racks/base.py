"""What every laboratory's rack has in common.

A rack is a laboratory's simulated world with its virtual instruments, registered under a
fresh id for the ``sim://NAME?rack=ID`` serial handler and the ``sim`` CAN interface
(``SimRack``); the server, the connection code and the truth see it through the ``Rack``
protocol. Drivers are opened the same way for every laboratory (``open_drivers``): one
per instrument, in order, each with the one constructor convention ``(name, link, clock,
timeout)``, all closed again if one fails to open.
"""

from __future__ import annotations

import itertools
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator, Mapping
from typing import Any, Protocol

import simpy

from instruments.base import ByteInstrument
from station.clock import Clock, VirtualClock
from station.drivers.driver_set import Driver, DriverFactory
from station.links import virtual
from station.numerics import pin_blas_threads

_ids: defaultdict[str, Iterator[int]] = defaultdict(lambda: itertools.count(1))


class Rack(Protocol):
    """A laboratory's simulated rack as the server, the connection code and truth see it."""

    rack_id: str
    env: simpy.Environment
    world: Any
    serial: dict[str, ByteInstrument]  # name -> instrument on a byte link
    can: dict[str, Any]  # name -> instrument on the CAN bus (the ISU's IEU)

    def close(self) -> None: ...


class SimRack:
    """Base of the laboratories' racks: the world, its instruments, the registration."""

    prefix = "rack"  # rack ids are <prefix><n>, numbered per laboratory in a process

    def __init__(self, world: Any, serial: dict[str, ByteInstrument],
                 can: dict[str, Any] | None = None) -> None:
        pin_blas_threads()  # the record's numbers must not depend on the machine's cores
        self.world = world
        self.env: simpy.Environment = world.env
        self.serial = serial
        self.can = dict(can or {})
        self.rack_id = f"{self.prefix}{next(_ids[self.prefix])}"
        virtual.register(virtual.VirtualRack(self.rack_id, self.env, dict(self.serial),
                                             dict(self.can)))

    def close(self) -> None:
        virtual.unregister(self.rack_id)

    def __enter__(self) -> SimRack:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def pin(url: str, rack_id: str | None) -> str:
    """A sim:// URL pinned to a particular rack (several racks may live in one process)."""
    if rack_id and url.startswith("sim://") and "rack=" not in url:
        return f"{url}{'&' if '?' in url else '?'}rack={rack_id}"
    return url


def sim_links(names: Iterable[str], rack: Rack) -> dict[str, str]:
    """``sim://NAME?rack=ID`` for each instrument of a local rack."""
    return {n: f"sim://{n}?rack={rack.rack_id}" for n in names}


def pick_links(names: Iterable[str], links: Mapping[str, Any], what: str) -> dict[str, Any]:
    """The link of each instrument from a served rack's (or a config's) map; ValueError
    naming the instruments it lacks."""
    names = list(names)
    missing = [n for n in names if n not in links]
    if missing:
        raise ValueError(f"no link for the {what} instrument(s) {', '.join(missing)} "
                         f"(links for: {', '.join(sorted(links)) or 'none'})")
    return {n: links[n] for n in names}


def open_drivers(factories: Mapping[str, DriverFactory], links: Mapping[str, Any],
                 clock: Clock | None, timeout: float) -> dict[str, Driver]:
    """One driver per instrument (``factory(name, link, clock, timeout)``), in order; if one
    fails to open, those already open are closed and the error goes on."""
    opened: dict[str, Driver] = {}
    try:
        for name, make in factories.items():
            opened[name] = make(name, links[name], clock, timeout)
    except BaseException:
        for d in opened.values():
            d.close()
        raise
    return opened


def rack_clock(rack: Rack | None, clock: Clock | None, what: str) -> Clock:
    """The clock of a station: the one given, else the local rack's virtual clock."""
    if clock is not None:
        return clock
    if rack is None:
        raise ValueError(f"a {what} station on links needs its clock")
    return VirtualClock(rack.env)


def open_sim_drivers(instruments: Mapping[str, DriverFactory], assemble: Callable[..., Any],
                     what: str, rack: Rack | None, timeout: float,
                     links: Mapping[str, Any] | None, clock: Clock | None) -> Any:
    """A laboratory of serial instruments only (CIGTF, ESG): its driver set on ``rack``
    (its ``sim://`` links; the clock defaults to its virtual clock) or on ``links``
    (instrument -> pyserial URL, e.g. the ptys of a served rack) with ``clock`` (a
    WallClock on the served rack's time). ``assemble(clock, drivers)`` makes the set."""
    if links is None:
        if rack is None:
            raise ValueError(f"open the {what} station on a rack or on links")
        links = sim_links(instruments, rack)
    clock = rack_clock(rack, clock, what)
    return assemble(clock, open_drivers(instruments, pick_links(instruments, links, what),
                                        clock, timeout))
