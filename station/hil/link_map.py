"""The link map a server publishes (``DIR/links.json``) and the driver settings it implies.

Each entry is ``{"instrument", "kind": "serial" | "can", "address"}``. A serial address is a
pty path (a pyserial URL). A CAN address is ``socketcand://HOST:PORT/CHANNEL`` or an slcan
pty path; :func:`can_config` turns either into the python-can settings IeuDriver takes.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from urllib.parse import urlparse

FILENAME = "links.json"


@dataclass(frozen=True)
class LinkEntry:
    instrument: str
    kind: str  # "serial" | "can"
    address: str


def write(links_dir: Path, entries: list[LinkEntry]) -> Path:
    """Write the map atomically, so that a reader never sees half of it."""
    path = links_dir / FILENAME
    tmp = links_dir / f".{FILENAME}.tmp"
    tmp.write_text(json.dumps([asdict(e) for e in entries], indent=2) + "\n")
    os.replace(tmp, path)
    return path


def read(path: Path) -> list[LinkEntry]:
    """Entries of a ``links.json`` file (or of ``DIR/links.json`` given the directory)."""
    if path.is_dir():
        path = path / FILENAME
    return [LinkEntry(**e) for e in json.loads(path.read_text())]


def can_config(address: str) -> dict:
    """python-can settings for a CAN address from the map."""
    if address.startswith("socketcand://"):
        u = urlparse(address)
        return {
            "interface": "socketcand",
            "host": u.hostname,
            "port": u.port,
            "channel": u.path.lstrip("/"),
        }
    return {"interface": "slcan", "channel": address, "sleep_after_open": 0}
