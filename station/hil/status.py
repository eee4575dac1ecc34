"""What a running rack server shows: a live table of its links and a plain status line.

It reads each link's :class:`~station.hil.counters.LinkCounters` (display-only, written by
the links' own threads) and never iterates a structure another thread may change (the
socketcand server sums its clients under its own lock). It sees the server through
:class:`ServedLinks`, what the display reads of it, not through the server module.

``render(server)`` is the rich table ``station serve`` keeps live on a terminal;
``status_line(server)`` the one line it prints every 10 s when stdout is a file.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from sim.timebase import seconds
from station.hil.counters import LinkCounters

if TYPE_CHECKING:
    from rich.console import Group

    from station.hil.realtime import RealtimeEnv
    from station.hil.serial_link import SerialPtyLink
    from station.hil.slcan import SlcanAdapter
    from station.hil.socketcand import SocketcandServer


class ServedLinks(Protocol):
    """What the status display reads of a rack server (station.hil.server.HilServer)."""

    @property
    def station(self) -> str: ...
    @property
    def session_id(self) -> str: ...
    @property
    def seed(self) -> int: ...
    @property
    def env(self) -> RealtimeEnv: ...
    @property
    def serial(self) -> Mapping[str, SerialPtyLink]: ...
    @property
    def can_instrument(self) -> str | None: ...
    @property
    def socketcand(self) -> SocketcandServer | None: ...
    @property
    def slcan(self) -> SlcanAdapter | None: ...


@dataclass(frozen=True)
class LinkRow:
    instrument: str
    kind: str  # "serial" | "socketcand" | "slcan"
    address: str
    device: str | None
    clients: int | None  # socketcand only
    counters: LinkCounters


def rows(server: ServedLinks) -> list[LinkRow]:
    """One row per link of the server, from a consistent-enough read of its counters."""
    out = [LinkRow(n, "serial", s.address, s.port.device, None, s.counters)
           for n, s in server.serial.items()]
    can = server.can_instrument or "ieu"
    if server.socketcand is not None:
        clients, counters = server.socketcand.snapshot()
        out.append(LinkRow(can, "socketcand", server.socketcand.address, None, clients,
                           counters))
    if server.slcan is not None:
        out.append(LinkRow(can, "slcan", server.slcan.address, server.slcan.port.device, None,
                           server.slcan.counters))
    return out


def _idle(c: LinkCounters, now: float) -> str:
    return "-" if c.last_at is None else f"{now - c.last_at:.1f}"


def simulated_now(server: ServedLinks) -> float:
    """The rack's time now, s: the wall mapping (simpy's ``now`` moves only at events)."""
    env = server.env
    return seconds(max(int(env.now), env.tick_at(time.monotonic())))


def header(server: ServedLinks) -> str:
    env = server.env
    return (f"station {server.station} | session {server.session_id} | seed {server.seed} | "
            f"speed {env.speed:g}x | t = {simulated_now(server):.1f} s simulated | slip "
            f"{env.slipped_s:.3f} s | {env.inputs_applied} inputs applied")


def render(server: ServedLinks) -> Group:
    """The live status: a header line and a table of the links (a rich renderable)."""
    from rich import box
    from rich.console import Group
    from rich.table import Table
    from rich.text import Text

    now = time.monotonic()
    t = Table(box=box.SIMPLE_HEAD, expand=False)
    right = ("clients", "in", "out", "bytes in", "bytes out", "idle s")
    for name in ("instrument", "kind", "address", "clients", "in", "out", "bytes in",
                 "bytes out", "last command", "idle s"):
        t.add_column(name, justify="right" if name in right else "left",
                     no_wrap=name != "address")
    for r in rows(server):
        c = r.counters
        addr = r.address if r.device is None else f"{r.address} -> {r.device}"
        t.add_row(r.instrument, r.kind, addr, "" if r.clients is None else str(r.clients),
                  str(c.rx_msgs), str(c.tx_msgs), str(c.rx_bytes), str(c.tx_bytes),
                  c.last_msg, _idle(c, now))
    note = Text("in/out: lines for serial links, frames for CAN; Ctrl-C stops", style="dim")
    return Group(Text(header(server), style="bold"), t, note)


def status_line(server: ServedLinks) -> str:
    """One plain line: the header and, per link, messages and bytes in/out."""
    parts = [header(server)]
    for r in rows(server):
        c = r.counters
        who = r.instrument if r.kind == "serial" else f"{r.instrument}/{r.kind}"
        extra = f" clients {r.clients}" if r.clients is not None else ""
        parts.append(f"{who}{extra} in {c.rx_msgs} out {c.tx_msgs} "
                     f"({c.rx_bytes}/{c.tx_bytes} B)")
    return "status: " + "; ".join(parts)


def held_line(server: ServedLinks) -> str | None:
    """Which links had their host's input held back by the line rate or a busy simulation
    (how often), or None if none did: a flood, or a rehearsal too fast for its links."""
    held = {n: s.port.held for n, s in server.serial.items()}
    if server.slcan is not None:
        held["ieu-slcan"] = server.slcan.port.held
    if server.socketcand is not None:
        held["ieu-socketcand"] = server.socketcand.held
    busy = [f"{n} {k}" for n, k in held.items() if k]
    return f"input held back (times): {', '.join(busy)}" if busy else None
