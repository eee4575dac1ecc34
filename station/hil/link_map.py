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
from station.hil.links_dir import write_text as links_dir_write

FILENAME = "links.json"


@dataclass(frozen=True)
class LinkEntry:
    instrument: str
    kind: str  # "serial" | "can"
    address: str


def write(links_dir: DirHandle | Path, entries: list[LinkEntry]) -> Path:
    """Write the map atomically (a reader never sees half of it), following no symlink."""
    text = json.dumps([asdict(e) for e in entries], indent=2) + "\n"
    return links_dir_write(links_dir, FILENAME, text)


class BadLinkMap(ValueError):
    """``links.json`` is not what a server writes (names the file and the entry)."""


KINDS = ("serial", "can")


def parse(text: str, where: str = FILENAME) -> list[LinkEntry]:
    """The entries of a map from its text; BadLinkMap if anything is off."""
    try:
        data = json.loads(text)
    except ValueError as e:
        raise BadLinkMap(f"{where}: not JSON ({e})") from None
    if not isinstance(data, list):
        raise BadLinkMap(f"{where}: not a JSON list")
    out = []
    for i, entry in enumerate(data, start=1):
        if not isinstance(entry, dict) or sorted(entry) != ["address", "instrument", "kind"]:
            raise BadLinkMap(f"{where}: entry {i} is not {{instrument, kind, address}}")
        if not all(isinstance(v, str) and v and v.isprintable() for v in entry.values()):
            raise BadLinkMap(f"{where}: entry {i}: every field must be a non-empty string")
        if entry["kind"] not in KINDS:
            raise BadLinkMap(f"{where}: entry {i}: kind must be serial or can, got "
                             f"{entry['kind']!r:.40}")
        out.append(LinkEntry(entry["instrument"], entry["kind"], entry["address"]))
    return out


def read(path: Path) -> list[LinkEntry]:
    """Entries of a ``links.json`` file (or of ``DIR/links.json`` given the directory);
    BadLinkMap if it is not a server's map."""
    if path.is_dir():
        path = path / FILENAME
    try:
        text = path.read_text()
    except UnicodeDecodeError as e:
        raise BadLinkMap(f"{path}: cannot read: {e}") from None
    return parse(text, str(path))


def can_config(address: str) -> dict:
    """python-can settings for a CAN address from the map; BadLinkMap if a socketcand
    address has no host or port."""
    if address.startswith("socketcand://"):
        u = urlparse(address)
        try:
            port = u.port
        except ValueError:
            port = None
        if not u.hostname or port is None:
            raise BadLinkMap(f"socketcand address {address!r:.60} needs a host and a port")
        return {
            "interface": "socketcand",
            "host": u.hostname,
            "port": u.port,
            "channel": u.path.lstrip("/"),
        }
    return {"interface": "slcan", "channel": address, "sleep_after_open": 0}
