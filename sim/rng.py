"""Seeded random streams: every random process draws from a stream named after it.

A stream depends only on (run seed, names), never on the order in which processes are
queried, so the same seed and config give the same world whatever the procedure does.
"""

from __future__ import annotations

import zlib

import numpy as np


def _key(name: str | int) -> int:
    if isinstance(name, int):
        return name
    return zlib.crc32(name.encode("utf-8"))


def stream(seed: int, *names: str | int) -> np.random.Generator:
    """A generator for the process identified by ``names`` under run ``seed``."""
    ss = np.random.SeedSequence(entropy=int(seed), spawn_key=tuple(_key(n) for n in names))
    return np.random.Generator(np.random.PCG64(ss))
