"""Embedded station configuration: the default TOML, the IEU's CAN database (DBC)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path


def path(name: str) -> Path:
    """Filesystem path of a file shipped in this package."""
    return Path(str(resources.files(__name__).joinpath(name)))


DEFAULT_CONFIG = "default.toml"
IEU_DBC = "ieu.dbc"
