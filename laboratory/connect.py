"""The ISU station a procedure command runs on: a simulated rack in virtual time, the
drivers alone over the links of a rack served in real time (``--links DIR``), or, when the
config's own links are device paths and socketcan, the laboratory's hardware.

Over links the procedures and drivers are the same; the differences are the link URLs
(from the server's ``links.json``), the clock (real time on the served rack's time base)
and ground truth: the coefficients of the served world are known only when the client's
config and seed are the server's (checked by the session's config digest), and the
attitude of the table only to the server, so alignment truth is absent over links.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from laboratory.check import needs_simulation
from laboratory.rundir import opened_journal, resume_note
from procedures.runner import Run
from sim.isu.world import World
from station.clock import WallClock
from station.config.isu import ConfigError, StationConfig
from station.hil import session
from station.hil.profile import ServedRun, WrongStation, attach
from station.hil.session import Session
from station.racks.isu import SimulatedRack, Station, open_station


@dataclass
class Connection:
    station: Station
    rack: SimulatedRack | None  # the local simulated rack (virtual run only)
    twin: SimulatedRack | None  # a never-run rack with the served world's seed and config
    session: Session | None  # the served rack's session (over links only)

    @property
    def coefficient_world(self) -> World | None:
        """A world whose true coefficients are those measured (None: unknown)."""
        r = self.rack or self.twin
        return r.world if r else None

    @property
    def attitude_world(self) -> World | None:
        """A world whose table attitude is the one measured (virtual runs only)."""
        return self.rack.world if self.rack else None

    def close(self) -> None:
        self.station.close()
        for r in (self.rack, self.twin):
            if r is not None:
                r.close()


def served_config(cfg: StationConfig, served: ServedRun) -> StationConfig:
    """``cfg`` with its links pointed at a served ISU rack."""
    missing = [n for n in cfg.links.serial if n not in served.links]
    if "ieu" not in served.can:
        missing.append("ieu")
    if missing:
        raise ConfigError(f"the rack served there does not serve {', '.join(missing)} "
                          "(was it started with --only?)")
    data = cfg.model_dump()
    data["links"] = {"serial": {n: served.links[n] for n in cfg.links.serial},
                     "can": served.can["ieu"]}
    return StationConfig.model_validate(data)


def connect(cfg: StationConfig, links_dir: Path | None = None,
            rack_hook: Callable[[SimulatedRack], None] | None = None,
            start_s: float = 0.0) -> Connection:
    """Drivers on a local simulated rack (``links_dir`` None) or on a served one.

    ``start_s`` (virtual only): let the rack run alone that long first, so that a virtual
    run begins at the simulated time a rehearsal against a served rack began.
    """
    if links_dir is None and not needs_simulation(cfg):  # the real laboratory: real time, no truth
        if start_s or rack_hook is not None:
            raise ValueError("start_s and rack_hook are for simulated racks only")
        return Connection(open_station(cfg, clock=WallClock()), None, None, None)
    if links_dir is None:
        rack = SimulatedRack(cfg)
        try:
            if rack_hook is not None:
                rack_hook(rack)
            st = open_station(cfg, rack)
            st.clock.sleep(start_s)
            return Connection(st, rack, None, None)
        except BaseException:
            rack.close()
            raise
    if start_s:
        raise ValueError("a served rack runs on its own time: start_s is for virtual runs")
    if rack_hook is not None:
        raise ValueError("faults for a served rack are configured in the server's config "
                         "([faults.<instrument>]), not injected by the client")
    served = attach(links_dir, "isu", cfg.seed, session.config_digest(cfg))
    st = open_station(served_config(cfg, served), clock=served.clock)
    return Connection(st, None, SimulatedRack(cfg) if served.truth else None, served.session)


def connect_rack(station: str, seed: int, digest: str, build_rack: Callable[[], Any],
                 open_fn: Callable[..., Any], links: Path | None = None,
                 rack_hook: Callable[[Any], None] | None = None) -> tuple[Any, Any, Any]:
    """The same choice for the CIGTF and ESG stations: ``(station, rack, served)``.

    Virtual: ``rack`` is the run's rack and ``served`` None. Over ``links``: ``served`` is
    the ``attach`` of the rack served there, and ``rack`` a never-run twin for the truth
    (None unless the served seed and config digest are the run's own).
    """
    served = None
    if links is not None:
        if rack_hook is not None:
            raise ValueError("rack_hook needs the local rack: not with links")
        served = attach(links, station, seed, digest)
    rack = build_rack() if served is None or served.truth else None
    if rack_hook is not None:
        rack_hook(rack)
    try:
        if served is None:
            st = open_fn(rack)
        else:
            try:
                st = open_fn(links=served.links, clock=served.clock)
            except ValueError as e:  # served with --only: instruments missing
                raise WrongStation(f"{links}: {e}") from None
    except BaseException:
        if rack is not None:
            rack.close()
        raise
    return st, rack, served


def served_session(records: list[dict]) -> str | None:
    """The served rack's session of a CIGTF or ESG journal's last start (None: virtual)."""
    starts = [r for r in records if r.get("event") == "start"]
    served = starts[-1].get("served") if starts else None
    return served.get("session") if isinstance(served, dict) else None


@contextmanager
def journaled_run(out: Path, st: Any, rack: Any, served: Any, resume: bool = False,
                  renew: tuple[str, ...] = (), **start: Any
                  ) -> Iterator[tuple[Run, dict, float]]:
    """The journal and Run of a CIGTF or ESG run on ``connect_rack``'s station:
    ``(run, served_record, t_start)``; the start note carries ``start`` and the served
    rack's record; the journal, drivers and rack are closed however the run ends.
    ``t_start`` is 0 in virtual time and the rack's time when served. ``resume``: the
    journal in ``out`` is continued, replayed in virtual time (each step checked against
    it), with its completed blocks restored over links; ``renew`` names the blocks a
    restarted rack (another session) must repeat even if completed (a warm-up)."""
    try:
        with opened_journal(out, resume) as journal:
            now = served.session.session if served is not None else None
            renewed = renew if resume and now != served_session(journal.records) else ()
            run = Run(st.clock, journal, resume="replay" if served is None else "skip",
                      repeat=renewed)
            if resume:
                resume_note(run)
            t_start = st.clock.now()
            extra = {} if served is None else {"served": served.record()}
            run.note(event="start", **start, **extra)
            yield run, extra, t_start
    finally:
        st.close()
        if rack is not None:
            rack.close()
