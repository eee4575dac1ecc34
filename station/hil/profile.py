"""A client's view of a served rack: link settings from ``links.json`` and the clock.

``served(DIR)`` reads the map and the session a server published under DIR and returns
the serial URLs by instrument, the python-can settings of the IEU (socketcand preferred:
it carries the rack's time and is the faster link) and a WallClock on the rack's time.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from station.clock import WallClock
from station.errors import UseError
from station.hil import link_map, session
from station.hil.session import Session


class NoServedRack(UseError, FileNotFoundError):
    """Nothing is served under the given directory (no links.json / session.json); exit 2,
    and still a FileNotFoundError for the callers that catch one."""


@dataclass(frozen=True)
class ServedLinks:
    serial: dict[str, str]  # instrument -> pyserial URL (a pty path)
    can: dict[str, dict]  # instrument -> python-can settings
    session: Session

    def clock(self) -> WallClock:
        """Real time on the rack's time base (its speed, its simulated-time origin)."""
        return WallClock(self.session.speed, self.session.t0_monotonic)


def served(links_dir: Path, can_kind: str = "socketcand") -> ServedLinks:
    """Links of the rack served under ``links_dir``; ``can_kind``: "socketcand" | "slcan"."""
    links_dir = Path(links_dir)
    try:
        s = session.read(links_dir)
        if s is None or not (links_dir / link_map.FILENAME).exists():
            raise NoServedRack(f"no served rack under {links_dir} (is `station serve` "
                               f"running with --links {links_dir}?)")
        serial: dict[str, str] = {}
        can: dict[str, dict] = {}
        for e in link_map.read(links_dir):
            if e.kind == "serial":
                serial[e.instrument] = e.address
            elif e.kind == "can":
                is_scd = e.address.startswith("socketcand://")
                if is_scd == (can_kind == "socketcand"):
                    can[e.instrument] = link_map.can_config(e.address)
    except (session.BadSession, link_map.BadLinkMap) as e:
        raise NoServedRack(f"no served rack under {links_dir}: {e}") from None
    except OSError as e:
        if isinstance(e, NoServedRack):
            raise
        raise NoServedRack(f"no served rack under {links_dir}: {e}") from None
    return ServedLinks(serial, can, s)


class WrongStation(UseError, ValueError):
    """The rack served under a links directory is not the station a command needs (exit 2;
    still a ValueError)."""


@dataclass(frozen=True)
class ServedRun:
    """A client's hold on a served rack: link URLs, the clock on the rack's time, the
    session, and whether ground truth may be computed locally (``truth``; ``note`` says why
    not)."""

    links: dict[str, str]  # serial instrument -> URL
    can: dict[str, dict]  # CAN instrument -> python-can settings
    clock: WallClock
    session: session.Session
    truth: bool
    note: str

    def record(self) -> dict:
        """What a run's journal and results keep about the served rack."""
        s = self.session
        return {"session": s.session, "station": s.station, "seed": s.seed, "speed": s.speed,
                "config_digest": s.config_digest, "truth": self.truth, "note": self.note}


def attach(links_dir: Path, station: str, seed: int, digest: str) -> ServedRun:
    """Links and clock of the ``station`` rack served under ``links_dir`` for a client whose
    own seed and config digest are ``seed``/``digest``: ground truth (from a rack built
    locally, never run) is only the served world's when both equal the session's.

    Raises ``profile.NoServedRack`` if nothing is served there (or its server is gone) and
    :class:`WrongStation` if another station is.
    """
    sv = served(Path(links_dir))
    s = sv.session
    try:
        os.kill(s.pid, 0)
    except ProcessLookupError:
        raise NoServedRack(f"the server (pid {s.pid}) that published {links_dir} is gone: "
                           "start `station serve` again") from None
    except PermissionError:
        pass  # alive, someone else's
    if s.station != station:
        raise WrongStation(f"{links_dir} serves the {s.station} station, not {station} "
                           f"(start `station serve --station {station} --links {links_dir}`)")
    diffs = []
    if s.seed != seed:
        diffs.append(f"seed {s.seed} (this run: {seed})")
    if s.config_digest != digest:
        diffs.append(f"config digest {s.config_digest} (this run: {digest})")
    note = ("served world = this run's seed and config: ground truth computed locally"
            if not diffs else
            f"served rack has {' and '.join(diffs)}: ground truth left out")
    return ServedRun(sv.serial, sv.can, sv.clock(), s, not diffs, note)
