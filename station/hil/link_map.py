"""The link map a server publishes (``DIR/links.json``) and the driver settings it implies.

Each entry is ``{"instrument", "kind": "serial" | "can", "address"}``. A serial address is a
pty path (a pyserial URL). A CAN address is ``socketcand://HOST:PORT/CHANNEL`` or an slcan
pty path; :func:`can_config` turns either into the python-can settings IeuDriver takes.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from urllib.parse import urlparse

from station.hil.links_dir import DirHandle

FILENAME = "links.json"


@dataclass(frozen=True)
class LinkEntry:
    instrument: str
    kind: str  # "serial" | "can"
    address: str


def write(links_dir: DirHandle | Path, entries: list[LinkEntry]) -> Path:
    """Write the map atomically (a reader never sees half of it), following no symlink."""
    text = json.dumps([asdict(e) for e in entries], indent=2) + "\n"
    if isinstance(links_dir, DirHandle):
        return links_dir.write_text(FILENAME, text)
    d = DirHandle(Path(links_dir))
    try:
        return d.write_text(FILENAME, text)
    finally:
        d.close()


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
