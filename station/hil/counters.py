"""Per-link traffic counters of a served rack, for display.

The link classes (``SerialPtyLink``, ``SocketcandServer`` and its clients, ``SlcanAdapter``)
each own a :class:`LinkCounters` and update its plain integer fields from their own
threads, every field from one thread only (the reader counts what comes in, the
simulation or writer thread what goes out). The counters take no lock: they are for
display (station.hil.status), never for control.
"""

from __future__ import annotations

import time

LAST_CHARS = 32  # of the last command shown


class LinkCounters:
    """Display-only counters of one link (each field has a single writing thread)."""

    __slots__ = ("rx_msgs", "tx_msgs", "rx_bytes", "tx_bytes", "last_msg", "last_at")

    def __init__(self) -> None:
        self.rx_msgs = 0  # lines, commands or frames from the host
        self.tx_msgs = 0  # replies, lines or frames to the host
        self.rx_bytes = 0
        self.tx_bytes = 0
        self.last_msg = ""  # the last command seen from the host (truncated)
        self.last_at: float | None = None  # time.monotonic() of the last traffic either way

    def touch(self) -> None:
        self.last_at = time.monotonic()

    def add(self, other: LinkCounters) -> None:
        """Accumulate ``other`` into this one (a snapshot, or a retired client's totals)."""
        self.rx_msgs += other.rx_msgs
        self.tx_msgs += other.tx_msgs
        self.rx_bytes += other.rx_bytes
        self.tx_bytes += other.tx_bytes
        if other.last_at is not None and (self.last_at is None or other.last_at > self.last_at):
            self.last_at = other.last_at
            self.last_msg = other.last_msg or self.last_msg


def short(text: bytes | str, n: int = LAST_CHARS) -> str:
    """Printable, truncated text of a command for display."""
    if isinstance(text, bytes):
        text = text.decode("ascii", "replace")
    text = "".join(c if c.isprintable() else "?" for c in text.strip())
    return text if len(text) <= n else text[: n - 1] + "~"
