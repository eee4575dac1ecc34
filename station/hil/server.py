"""The rack server: a simulated rack in real time, its instruments on OS-level links.

``station serve [--station NAME] ...`` (laboratory/cli.py) builds a laboratory's rack on a
:class:`RealtimeEnv` through the registry and hands it here: :class:`HilServer` serves each
selected serial instrument on a raw pty (symlink ``DIR/<name>``) and the rack's CAN
instrument, if it has one (the ISU's IEU), on a socketcand server on 127.0.0.1 and on
slcan (symlink ``DIR/<name>-slcan``), writes ``DIR/session.json`` and ``DIR/links.json``
once every link is up, prints the map, and runs until SIGTERM/SIGINT: with a live status
table on a terminal, else with a plain status line every 10 s. A failure of the
simulation itself stops the server (exit status 1).

A rack is a ``station.racks.base.Rack`` (its environment, ``serial`` and ``can``
instruments, ``close``); :class:`ServedStation` says how to build one and what the
session publishes about it. The server knows no laboratory by name.
"""

from __future__ import annotations

import gc
import logging
import os
import signal
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from station.hil import link_map, session, status
from station.hil.can_hub import CanHub
from station.hil.link_map import LinkEntry
from station.hil.links_dir import LinksDir
from station.hil.realtime import RealtimeEnv
from station.hil.serial_link import SerialPtyLink
from station.hil.slcan import SlcanAdapter
from station.hil.socketcand import SocketcandServer

if TYPE_CHECKING:
    from rich.console import RenderableType

log = logging.getLogger("station.hil")

GIL_SWITCH_S = 0.001  # s; Python's default is 0.005
STATUS_EVERY_S = 10.0  # wall seconds between plain status lines (stdout not a terminal)
LIVE_REFRESH_PER_S = 2.0


@dataclass(frozen=True)
class ServedStation:
    """Which station to serve: its name, seed and config digest (published in the session)
    and how to build its rack on the server's real-time environment."""

    station: str
    seed: int
    config_digest: str
    build: Callable[[RealtimeEnv], Any]


class HilServer:
    """Owns the real-time environment, the rack, the links and the simulation thread."""

    def __init__(
        self,
        target: ServedStation,
        speed: float,
        links_dir: Path,
        only: Iterable[str] | None = None,
        can_host: str = "127.0.0.1",
        can_port: int = 0,
        max_lag_s: float = 0.05,
    ) -> None:
        # first of all: a second server on this directory is refused before touching it
        self.directory = LinksDir(Path(links_dir))
        self.links_dir = self.directory.path
        spec = target
        self.station = spec.station
        self.seed = spec.seed
        self.config_digest = spec.config_digest
        try:
            self.env = RealtimeEnv(speed, max_lag_s)
            self.session_id = uuid.uuid4().hex[:12]
            self.rack = spec.build(self.env)
        except BaseException:
            self.directory.close()
            raise
        if self.rack.env is not self.env:
            self.rack.close()
            self.directory.close()
            raise ValueError(f"the {self.station} rack was not built on the server's environment")
        if len(self.rack.can) > 1:
            self.rack.close()
            self.directory.close()
            raise ValueError(f"the {self.station} rack has {len(self.rack.can)} CAN "
                             "instruments: the server serves one CAN bus")
        self.can_instrument: str | None = next(iter(self.rack.can), None)
        self.serial: dict[str, SerialPtyLink] = {}
        self.hub: CanHub | None = None
        self.socketcand: SocketcandServer | None = None
        self.slcan: SlcanAdapter | None = None
        self.error: BaseException | None = None
        self.done = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sim", daemon=True)
        self._map_path: Path | None = None
        self._session_path: Path | None = None
        try:
            names = self._select(only)
            for n in names:
                if n != self.can_instrument:
                    link = self.links_dir / n
                    self.serial[n] = SerialPtyLink(self.env, self.rack.serial[n], link,
                                                   self.directory)
            if self.can_instrument is not None and self.can_instrument in names:
                can = self.rack.can[self.can_instrument]
                can.serve_in_real_time(speed)
                self.hub = CanHub(self.env, can)
                self.socketcand = SocketcandServer(self.hub, self.can_instrument, can_host,
                                                   can_port)
                slcan = self.slcan_link
                self.slcan = SlcanAdapter(self.hub, slcan, self.links_dir / slcan,
                                          self.directory)
        except BaseException:
            self.close()
            raise

    @property
    def slcan_link(self) -> str:
        """The symlink of the CAN instrument's slcan port (``ieu-slcan``)."""
        return f"{self.can_instrument}-slcan"

    def _select(self, only: Iterable[str] | None) -> list[str]:
        known = [*self.rack.serial, *([self.can_instrument] if self.can_instrument else [])]
        if only is None:
            return known
        names = [n.strip() for n in only if n.strip()]
        unknown = [n for n in names if n not in known]
        if unknown or not names:
            raise ValueError(
                f"unknown instrument(s) {', '.join(unknown) or '(none given)'}; "
                f"known to the {self.station} station: {', '.join(known)}"
            )
        return [n for n in known if n in names]

    def entries(self) -> list[LinkEntry]:
        out = [LinkEntry(n, "serial", s.address) for n, s in self.serial.items()]
        if self.socketcand is not None:
            out.append(LinkEntry(str(self.can_instrument), "can", self.socketcand.address))
        if self.slcan is not None:
            out.append(LinkEntry(str(self.can_instrument), "can", self.slcan.address))
        return out

    def devices(self) -> dict[str, str]:
        """Symlink address -> pty device, for display."""
        ports = [s.port for s in self.serial.values()]
        if self.slcan is not None:
            ports.append(self.slcan.port)
        return {p.address: p.device for p in ports}

    def start(self) -> Path:
        """Start every link and the simulation; then publish the map (readiness signal)."""
        for s in self.serial.values():
            s.start()
        if self.socketcand is not None:
            self.socketcand.start()
        if self.slcan is not None:
            self.slcan.start()
        self._thread.start()
        while not self.env.running and not self.done.is_set():
            time.sleep(0.001)  # the simulation thread anchors its time base first
        self.publish_session()
        self._map_path = link_map.write(self.directory, self.entries())
        return self._map_path

    def session(self) -> session.Session:
        return session.Session(
            session=self.session_id, station=self.station, seed=self.seed, speed=self.env.speed,
            config_digest=self.config_digest, t0_monotonic=self.env.wall_at(0),
            pid=os.getpid(),
        )

    def publish_session(self) -> None:
        """(Re)write session.json: the time base moves when the physics slips behind."""
        self._session_path = session.write(self.directory, self.session())

    def _run(self) -> None:
        try:
            self.env.run_realtime()
        except BaseException as e:
            self.error = e
            log.exception("simulation failed at t = %.6f s", self.env.now_s)
        finally:
            self.done.set()

    def stop(self) -> None:
        """Ask the simulation thread to finish (any thread, signal handlers included)."""
        self.env.stop()

    def close(self) -> None:
        """Stop everything, remove what the server published (symlinks, links.json,
        session.json) and let go of the links directory."""
        self.env.stop()
        if self._thread.is_alive():
            self._thread.join(10.0)
        for attr in ("_map_path", "_session_path"):
            path = getattr(self, attr)
            if path is not None:
                self.directory.unlink(path.name)
                setattr(self, attr, None)
        if self.socketcand is not None:
            self.socketcand.close()
        if self.slcan is not None:
            self.slcan.close()
        for s in self.serial.values():
            s.close()
        self.rack.close()
        self.directory.close()

    def __enter__(self) -> HilServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _print_map(server: HilServer) -> None:
    devices = server.devices()
    print(f"station HIL server (pid {os.getpid()}): station {server.station}, seed "
          f"{server.seed}, speed {server.env.speed:g}x, session {server.session_id}")
    for e in server.entries():
        dev = devices.get(e.address)
        extra = f"  -> {dev}" if dev else ""
        print(f"  {e.instrument:<16} {e.kind:<7} {e.address}{extra}")
    print(f"link map: {server.links_dir / link_map.FILENAME}", flush=True)


def serve(
    target: ServedStation,
    speed: float,
    links_dir: str | Path,
    only: Iterable[str] | None = None,
    can_port: int = 0,
    live: bool | None = None,
) -> None:
    """Serve a rack until SIGTERM/SIGINT (or :meth:`HilServer.stop`); raise if the sim fails.

    ``target``: the ServedStation. ``live``: keep a rich
    status table on screen (default: when stdout is a terminal); otherwise print a plain
    status line every STATUS_EVERY_S wall seconds.
    """
    switch = sys.getswitchinterval()
    # I/O threads take their arrival time once they hold the GIL: keep that wait short
    sys.setswitchinterval(min(switch, GIL_SWITCH_S))
    if live is None:
        live = sys.stdout.isatty()
    try:
        with HilServer(target, speed, Path(links_dir), only, can_port=can_port) as server:
            _settle_heap()
            _serve_until_stopped(server, live)
    finally:
        sys.setswitchinterval(switch)


def _settle_heap() -> None:
    """Collect once, then exempt everything built so far (the rack: it lives as long as
    the process) from later full collections, which would otherwise walk the whole rack
    in whichever thread triggers them and stall every link for tens of milliseconds
    (measured: 50-60 ms, a slip of the time base); from then on, time the pauses."""
    gc.collect()
    gc.freeze()
    GC_PAUSES.clear()
    GC_PAUSES.update(longest=0.0, count=0)
    if _time_gc not in gc.callbacks:
        gc.callbacks.append(_time_gc)


GC_PAUSES: dict[str, float] = {}  # since served: "count", "longest" pause s, "started" at


def _time_gc(phase: str, info: dict) -> None:
    now = time.monotonic()
    if phase == "start":
        GC_PAUSES["started"] = now
    elif "started" in GC_PAUSES:
        pause = now - GC_PAUSES.pop("started")
        GC_PAUSES["longest"] = max(pause, GC_PAUSES["longest"])
        GC_PAUSES["count"] += 1


def _watch(server: HilServer, tick: Callable[[], None] | None = None) -> None:
    """Until the simulation stops: re-publish the session when the time base slips; call
    ``tick`` about every STATUS_EVERY_S seconds."""
    published = 0.0
    next_tick = time.monotonic() + STATUS_EVERY_S
    while not server.done.wait(0.5):
        if server.env.slipped_s - published > 1e-3:  # the time base moved
            published = server.env.slipped_s
            server.publish_session()
        if tick is not None and time.monotonic() >= next_tick:
            next_tick += STATUS_EVERY_S
            tick()


def _live_table(server: HilServer) -> RenderableType:
    try:
        return status.render(server)
    except Exception as e:  # a display bug must not take the server down
        from rich.text import Text

        return Text(f"status unavailable: {e!r}")


def _watch_live(server: HilServer) -> None:
    """_watch under a rich Live status table; log records go above the table meanwhile."""
    from rich.console import Console
    from rich.live import Live

    with Live(console=Console(), get_renderable=lambda: _live_table(server),
              refresh_per_second=LIVE_REFRESH_PER_S, redirect_stdout=True,
              redirect_stderr=True):
        # handlers made before Live hold the real stderr: point them at Live's proxy
        moved = []
        for h in logging.getLogger().handlers:
            if type(h) is logging.StreamHandler and h.stream in (sys.__stderr__, sys.__stdout__):
                moved.append((h, h.setStream(sys.stderr)))
        try:
            _watch(server)
        finally:
            for h, stream in moved:
                h.setStream(stream)


def _serve_until_stopped(server: HilServer, live: bool = False) -> None:
    handlers = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGTERM, signal.SIGINT):
            handlers[sig] = signal.signal(sig, lambda *_: server.stop())
    try:
        server.start()
        _print_map(server)
        if live:
            _watch_live(server)
        else:
            _watch(server, lambda: print(status.status_line(server), flush=True))
    finally:
        for sig, h in handlers.items():
            signal.signal(sig, h)
    env = server.env
    t = env.now_s if server.error is not None else status.simulated_now(server)
    held = status.held_line(server)
    if held:
        print(held, flush=True)
    if "count" in GC_PAUSES:
        print(f"garbage collections while serving: {GC_PAUSES['count']:.0f}, longest pause "
              f"{GC_PAUSES['longest'] * 1e3:.1f} ms", flush=True)
    print(
        f"stopped at t = {t:.3f} s simulated; "
        f"{env.inputs_applied} inputs applied; "
        f"slipped {env.slipped_s:.3f} s behind real time",
        flush=True,
    )
    if server.error is not None:
        raise RuntimeError(f"simulation failed: {server.error!r}") from server.error
