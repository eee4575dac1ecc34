"""`station check`: talk to every instrument of a laboratory over its link and report who
answers (the rack's local simulation, a served rack's links, or the configured hardware)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from laboratory.connect import served_links
from laboratory.registry import Laboratory
from station.errors import StationError
from station.hil.profile import attach
from station.racks.base import Rack


@dataclass
class CheckResult:
    instrument: str
    link: str
    ok: bool
    identity: str


def shown_link(link: Any) -> str:
    """A link as the operator names it: a URL without its rack pin, a CAN bus as
    ``interface:channel``."""
    if isinstance(link, dict):
        return f"{link.get('interface')}:{link.get('channel')}"
    url = str(link)
    base, _, query = url.partition("?")
    rest = "&".join(q for q in query.split("&") if q and not q.startswith("rack="))
    return f"{base}?{rest}" if rest else base


def check_all(lab: Laboratory, cfg: Any, links_dir: Path | None = None,
              timeout: float = 2.0) -> list[CheckResult]:
    """Open each instrument's driver alone on its link, ask its identity, close it."""
    rack: Rack | None = None
    if links_dir is not None:
        links = served_links(lab, attach(links_dir, lab.name, lab.seed_of(cfg),
                                         lab.digest(cfg)), links_dir)
    elif lab.simulated(cfg):
        rack = lab.build_rack(cfg, None)
        links = lab.links(cfg, rack)
    else:
        links = lab.links(cfg, None)
    out: list[CheckResult] = []
    try:
        for name, make in lab.drivers().items():
            link = shown_link(links[name])
            try:
                drv = make(name, links[name], None, timeout)
                try:
                    out.append(CheckResult(name, link, True, drv.identify()))
                finally:
                    drv.close()
            except StationError as e:
                out.append(CheckResult(name, link, False, str(e)))
    finally:
        if rack is not None:
            rack.close()
    return out


def as_dicts(results: list[CheckResult]) -> list[dict]:
    return [asdict(r) for r in results]
