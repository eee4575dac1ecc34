"""A laboratory's open drivers and the clock they share: what a procedure receives.

Each laboratory declares its set as a dataclass of driver types (``IsuDrivers``,
``CigtfDrivers``, ``EsgDrivers``); the set imports only drivers and the clock, never the
simulator, so a procedure typed against it cannot reach ``sim`` or ``instruments``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from typing import Any, ClassVar, Protocol, Self

from station.clock import Clock


class Driver(Protocol):
    """What every driver has (serial ones through ``SerialDriver``, the IEU on CAN)."""

    name: str

    def bind_clock(self, clock: Clock) -> None: ...

    def identify(self) -> str: ...

    def close(self) -> None: ...


# how a driver is made: the one convention (name, link, clock or None, timeout)
DriverFactory = Callable[[str, Any, Clock | None, float], Driver]


@dataclass
class DriverSet:
    """The clock and the drivers of one laboratory; fields holding a driver, or a dict of
    drivers (counters by number), are its drivers, in declaration order."""

    clock: Clock
    # field -> instrument name where they differ (the CIGTF's ``power`` is ``gyro_power``)
    instrument_of: ClassVar[dict[str, str]] = {}

    @classmethod
    def assemble(cls, clock: Clock, opened: Mapping[str, Driver], **extra: Any) -> Self:
        """The set from drivers opened by instrument name (one per driver field)."""
        names = [f.name for f in fields(cls) if f.name != "clock" and f.name not in extra]
        drivers: dict[str, Any] = {n: opened[cls.instrument_of.get(n, n)] for n in names}
        return cls(clock=clock, **drivers, **extra)

    def drivers(self) -> list[Driver]:
        out: list[Driver] = []
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, dict):
                out += [d for d in v.values() if hasattr(d, "bind_clock")]
            elif f.name != "clock" and hasattr(v, "bind_clock"):
                out.append(v)
        return out

    def close(self) -> None:
        for d in self.drivers():
            d.close()
