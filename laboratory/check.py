"""`station check`: talk to every instrument over its configured link and report who answers."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from station.config.isu import SERIAL_INSTRUMENTS, StationConfig
from station.drivers.isu.ieu import IeuDriver
from station.drivers.serial_base import SerialDriver
from station.errors import StationError
from station.racks.isu import SimulatedRack, _bind, can_config


@dataclass
class CheckResult:
    instrument: str
    link: str
    ok: bool
    identity: str


def needs_simulation(cfg: StationConfig) -> bool:
    return any(u.startswith("sim://") for u in cfg.links.serial.values()) or (
        cfg.links.can.interface == "sim"
    )


def check_all(cfg: StationConfig, timeout: float = 2.0) -> list[CheckResult]:
    rack = SimulatedRack(cfg) if needs_simulation(cfg) else None
    rid = rack.rack_id if rack else None
    out: list[CheckResult] = []
    try:
        for name in SERIAL_INSTRUMENTS:
            url = cfg.links.serial[name]
            try:
                drv = SerialDriver(name, _bind(url, rid), timeout)
                try:
                    out.append(CheckResult(name, url, True, drv.identify()))
                finally:
                    drv.close()
            except StationError as e:
                out.append(CheckResult(name, url, False, str(e)))
        can_cfg = can_config(cfg, rid)
        link = f"{cfg.links.can.interface}:{cfg.links.can.channel}"
        try:
            ieu = IeuDriver(can_cfg, timeout=timeout)
            try:
                out.append(CheckResult("ieu", link, True, ieu.identify()))
            finally:
                ieu.close()
        except StationError as e:
            out.append(CheckResult("ieu", link, False, str(e)))
    finally:
        if rack:
            rack.close()
    return out


def as_dicts(results: list[CheckResult]) -> list[dict]:
    return [asdict(r) for r in results]
