"""The rack server: the simulated rack in real time, its instruments on OS-level links.

``python -m station.hil.server [--config FILE] [--seed N] [--speed X] --links DIR
[--only name,...] [--can-port P]`` builds the SimulatedRack on a :class:`RealtimeEnv`,
serves each selected serial instrument on a raw pty (symlink ``DIR/<name>``) and the IEU
on a socketcand server on 127.0.0.1 and on slcan (symlink ``DIR/ieu-slcan``), writes
``DIR/links.json`` once every link is up, prints the map, and runs until SIGTERM/SIGINT.
A failure of the simulation itself stops the server with exit status 1.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading
import time
import uuid
from collections.abc import Iterable
from pathlib import Path

from station.config import ConfigError, StationConfig, load_config
from station.hil import link_map, session
from station.hil.can_hub import CanHub
from station.hil.link_map import LinkEntry
from station.hil.realtime import RealtimeEnv
from station.hil.serial_link import SerialPtyLink
from station.hil.slcan import SlcanAdapter
from station.hil.socketcand import SocketcandServer
from station.rack import SimulatedRack

log = logging.getLogger("station.hil")

CAN_INSTRUMENT = "ieu"
SLCAN_LINK = "ieu-slcan"
GIL_SWITCH_S = 0.001  # s; Python's default is 0.005


class HilServer:
    """Owns the real-time environment, the rack, the links and the simulation thread."""

    def __init__(
        self,
        cfg: StationConfig,
        speed: float,
        links_dir: Path,
        only: Iterable[str] | None = None,
        can_host: str = "127.0.0.1",
        can_port: int = 0,
        max_lag_s: float = 0.05,
    ) -> None:
        self.links_dir = Path(links_dir).resolve()
        self.links_dir.mkdir(parents=True, exist_ok=True)
        for stale in (link_map.FILENAME, session.FILENAME):  # a dead server's files
            (self.links_dir / stale).unlink(missing_ok=True)
        self.env = RealtimeEnv(speed, max_lag_s)
        self.cfg = cfg
        self.session_id = uuid.uuid4().hex[:12]
        self.rack = SimulatedRack(cfg, env=self.env)
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
                if n != CAN_INSTRUMENT:
                    link = self.links_dir / n
                    self.serial[n] = SerialPtyLink(self.env, self.rack.serial[n], link)
            if CAN_INSTRUMENT in names:
                self.hub = CanHub(self.env, self.rack.ieu)
                self.socketcand = SocketcandServer(self.hub, CAN_INSTRUMENT, can_host, can_port)
                self.slcan = SlcanAdapter(self.hub, SLCAN_LINK, self.links_dir / SLCAN_LINK)
        except BaseException:
            self.close()
            raise

    def _select(self, only: Iterable[str] | None) -> list[str]:
        known = [*self.rack.serial, CAN_INSTRUMENT]
        if only is None:
            return known
        names = [n.strip() for n in only if n.strip()]
        unknown = [n for n in names if n not in known]
        if unknown or not names:
            raise ValueError(
                f"unknown instrument(s) {', '.join(unknown) or '(none given)'}; "
                f"known: {', '.join(known)}"
            )
        return [n for n in known if n in names]

    def entries(self) -> list[LinkEntry]:
        out = [LinkEntry(n, "serial", s.address) for n, s in self.serial.items()]
        if self.socketcand is not None:
            out.append(LinkEntry(CAN_INSTRUMENT, "can", self.socketcand.address))
        if self.slcan is not None:
            out.append(LinkEntry(CAN_INSTRUMENT, "can", self.slcan.address))
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
        self._map_path = link_map.write(self.links_dir, self.entries())
        return self._map_path

    def session(self) -> session.Session:
        return session.Session(
            session=self.session_id, station="isu", seed=self.cfg.seed, speed=self.env.speed,
            config_digest=session.config_digest(self.cfg), t0_monotonic=self.env.wall_at(0),
            pid=os.getpid(),
        )

    def publish_session(self) -> None:
        """(Re)write session.json: the time base moves when the physics slips behind."""
        self._session_path = session.write(self.links_dir, self.session())

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
        """Stop everything and remove what the server published (symlinks, links.json)."""
        self.env.stop()
        if self._thread.is_alive():
            self._thread.join(10.0)
        for attr in ("_map_path", "_session_path"):
            path = getattr(self, attr)
            if path is not None:
                path.unlink(missing_ok=True)
                setattr(self, attr, None)
        if self.socketcand is not None:
            self.socketcand.close()
        if self.slcan is not None:
            self.slcan.close()
        for s in self.serial.values():
            s.close()
        self.rack.close()

    def __enter__(self) -> HilServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _print_map(server: HilServer, speed: float, cfg: StationConfig) -> None:
    devices = server.devices()
    print(f"station HIL server (pid {os.getpid()}): seed {cfg.seed}, speed {speed:g}x")
    for e in server.entries():
        dev = devices.get(e.address)
        extra = f"  -> {dev}" if dev else ""
        print(f"  {e.instrument:<16} {e.kind:<7} {e.address}{extra}")
    print(f"link map: {server.links_dir / link_map.FILENAME}", flush=True)


def serve(
    cfg: StationConfig,
    speed: float,
    links_dir: str | Path,
    only: Iterable[str] | None = None,
    can_port: int = 0,
) -> None:
    """Serve the rack until SIGTERM/SIGINT (or :meth:`HilServer.stop`); raise if the sim fails."""
    switch = sys.getswitchinterval()
    # I/O threads take their arrival time once they hold the GIL: keep that wait short
    sys.setswitchinterval(min(switch, GIL_SWITCH_S))
    try:
        with HilServer(cfg, speed, Path(links_dir), only, can_port=can_port) as server:
            _serve_until_stopped(server, speed, cfg)
    finally:
        sys.setswitchinterval(switch)


def _serve_until_stopped(server: HilServer, speed: float, cfg: StationConfig) -> None:
    handlers = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGTERM, signal.SIGINT):
            handlers[sig] = signal.signal(sig, lambda *_: server.stop())
    try:
        server.start()
        _print_map(server, speed, cfg)
        published = 0.0
        while not server.done.wait(1.0):
            if server.env.slipped_s - published > 1e-3:  # the time base moved
                published = server.env.slipped_s
                server.publish_session()
    finally:
        for sig, h in handlers.items():
            signal.signal(sig, h)
    env = server.env
    print(
        f"stopped at t = {env.now_s:.3f} s simulated; {env.inputs_applied} inputs applied; "
        f"slipped {env.slipped_s:.3f} s behind real time",
        flush=True,
    )
    if server.error is not None:
        raise RuntimeError(f"simulation failed: {server.error!r}") from server.error


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m station.hil.server",
        description="Serve the simulated rack in real time on ptys, socketcand and slcan.",
    )
    p.add_argument("--config", type=Path, help="station config TOML (merged over the default)")
    p.add_argument("--seed", type=int, help="run seed (default: the config's)")
    p.add_argument("--speed", type=float, default=1.0, help="simulated seconds per wall second")
    p.add_argument("--links", type=Path, required=True, help="directory for symlinks, links.json")
    p.add_argument("--only", help="comma-separated instruments to serve (default: all)")
    p.add_argument("--can-port", type=int, default=0, help="socketcand TCP port (0: any free)")
    a = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    try:
        cfg = load_config(a.config, seed=a.seed)
        serve(cfg, a.speed, a.links, a.only.split(",") if a.only else None, a.can_port)
    except (ConfigError, ValueError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except RuntimeError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
