"""A client's view of a served rack: link settings from ``links.json`` and the clock.

``served(DIR)`` reads the map and the session a server published under DIR and returns
the serial URLs by instrument, the python-can settings of the IEU (socketcand preferred:
it carries the rack's time and is the faster link) and a WallClock on the rack's time.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from station.clock import WallClock
from station.hil import link_map, session
from station.hil.session import Session


class NoServedRack(FileNotFoundError):
    """Nothing is served under the given directory (no links.json / session.json)."""


@dataclass(frozen=True)
class ServedLinks:
    serial: dict[str, str]  # instrument -> pyserial URL (a pty path)
    can: dict[str, dict]  # instrument -> python-can settings
    session: Session

    def clock(self) -> WallClock:
        """Real time on the rack's time base (its speed, its simulated-time origin)."""
        return WallClock(self.session.speed, self.session.t0_monotonic)


def served(links_dir: Path, can_kind: str = "socketcand") -> ServedLinks:
    """Links of the rack served under ``links_dir``; ``can_kind``: "socketcand" | "slcan"."""
    links_dir = Path(links_dir)
    s = session.read(links_dir)
    if s is None or not (links_dir / link_map.FILENAME).exists():
        raise NoServedRack(f"no served rack under {links_dir} (is `station serve` running "
                           f"with --links {links_dir}?)")
    serial: dict[str, str] = {}
    can: dict[str, dict] = {}
    for e in link_map.read(links_dir):
        if e.kind == "serial":
            serial[e.instrument] = e.address
        elif e.kind == "can":
            is_scd = e.address.startswith("socketcand://")
            if is_scd == (can_kind == "socketcand"):
                can[e.instrument] = link_map.can_config(e.address)
    return ServedLinks(serial, can, s)
