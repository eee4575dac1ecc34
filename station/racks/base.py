"""Opening a station of serial instruments (CIGTF, ESG) on a local rack or on links.

One place for what both do: a URL per instrument (``sim://NAME?rack=ID`` of a local rack,
or the ptys of a served rack), the clock (the rack's virtual clock, or the WallClock a
served rack needs), drivers opened in order and closed again if one fails, and every
driver's link timeouts bound to the clock.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from station.clock import Clock, VirtualClock


def station_links(names, rack_id: str | None, links: dict[str, str] | None,
                  what: str) -> dict[str, str]:
    """URL per instrument: ``sim://NAME?rack=ID`` of a local rack, or the given ``links``."""
    if links is None:
        if rack_id is None:
            raise ValueError(f"open the {what} station on a rack or on links")
        return {n: f"sim://{n}?rack={rack_id}" for n in names}
    missing = [n for n in names if n not in links]
    if missing:
        raise ValueError(f"no link for the {what} instrument(s) {', '.join(missing)} "
                         f"(links for: {', '.join(sorted(links)) or 'none'})")
    return dict(links)


def open_drivers(rack: Any | None, links: dict[str, str] | None, clock: Clock | None,
                 what: str, factories: dict[str, Callable[[str, Clock], Any]]
                 ) -> tuple[Clock, list]:
    """``(clock, drivers)``: one driver per factory, in order, on the rack or the links."""
    url = station_links(list(factories), rack.rack_id if rack else None, links, what)
    if clock is None:
        if rack is None:
            raise ValueError(f"a {what} station on links needs its clock")
        clock = VirtualClock(rack.env)
    opened: list = []
    try:
        for name, make in factories.items():
            opened.append(make(url[name], clock))
    except BaseException:
        for d in opened:
            d.close()
        raise
    for d in opened:
        d.bind_clock(clock)
    return clock, opened
