"""The station a procedure command runs on, for any laboratory of the registry: a
simulated rack in virtual time, the drivers alone over the links of a rack served in real
time (``--links DIR``), or, when the config's own links reach hardware (the ISU
laboratory's device paths and socketcan), the laboratory's hardware.

Over links the procedures and drivers are the same; the differences are the link URLs
(from the server's ``links.json``), the clock (real time on the served rack's time base)
and ground truth: the served world's static truth is known only when the client's config
and seed are the server's (checked by the session's config digest: a never-run twin rack
is built for it), and its time-varying state (the table's attitude, a rotor's path) only
to the server, so that truth is absent over links.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from laboratory import startup
from laboratory.history import index_after
from laboratory.identity import Identifying, identified
from laboratory.registry import Laboratory
from laboratory.report import report_after
from laboratory.rundir import opened_journal, resume_note
from procedures.runner import Run
from station.clock import Clock, WallClock
from station.drivers.driver_set import DriverSet
from station.racks.base import Rack, open_drivers

if TYPE_CHECKING:  # the server brings every laboratory's CAN hub (the ISU's IEU): on use only
    from station.hil.profile import ServedRun
    from station.hil.server import ServedStation
    from station.hil.session import Session


@dataclass
class Connection:
    """What a command runs on: the laboratory's drivers and what stands behind them."""

    drivers: Any  # the laboratory's DriverSet (IsuDrivers, CigtfDrivers, EsgDrivers ...)
    rack: Rack | None  # the local simulated rack (virtual run only)
    twin: Rack | None  # a never-run rack with the served world's seed and config
    served: ServedRun | None  # the served rack attached to (over links only)

    @property
    def station(self) -> Any:
        """The drivers (the name procedures and older callers use)."""
        return self.drivers

    @property
    def session(self) -> Session | None:
        return self.served.session if self.served is not None else None

    @property
    def coefficient_world(self) -> Any:
        """A world whose static truth is that of the world measured (None: unknown)."""
        r = self.rack or self.twin
        return r.world if r else None

    @property
    def attitude_world(self) -> Any:
        """A world whose time-varying state is the one measured (virtual runs only)."""
        return self.rack.world if self.rack else None

    def close(self) -> None:
        self.drivers.close()
        for r in (self.rack, self.twin):
            if r is not None:
                r.close()


def served_station(lab: Laboratory, cfg: Any) -> ServedStation:
    """What ``station serve`` serves of a laboratory: its seed and config digest (the
    session publishes them) and how to build its rack on the server's environment."""
    from station.hil.server import ServedStation

    return ServedStation(lab.name, lab.seed_of(cfg), lab.digest(cfg),
                         lambda env: lab.build_rack(cfg, env))


def open_station(lab: Laboratory, cfg: Any, links: dict[str, Any], clock: Clock,
                 timeout: float = 5.0) -> DriverSet:
    """The laboratory's drivers on ``links`` (instrument -> link) with ``clock``."""
    opened = open_drivers(lab.drivers(), links, clock, timeout)
    return lab.assemble(clock, opened, links)


def served_links(lab: Laboratory, served: ServedRun, links_dir: Path) -> dict[str, Any]:
    """Each instrument's link on the served rack; WrongStation naming what it lacks (a rack
    served with --only)."""
    offered = {**served.links, **served.can}
    names = list(lab.drivers())
    missing = [n for n in names if n not in offered]
    if missing:
        from station.hil.profile import WrongStation

        raise WrongStation(f"{links_dir}: the rack served there does not serve "
                           f"{', '.join(missing)} (was it started with --only?)")
    return {n: offered[n] for n in names}


def connect(lab: Laboratory, cfg: Any, links_dir: Path | None = None,
            rack_hook: Callable[[Any], None] | None = None,
            start_s: float = 0.0, timeout: float = 5.0) -> Connection:
    """Drivers on a local simulated rack (``links_dir`` None), on a served one, or on the
    hardware the config's links name.

    ``start_s`` (virtual only): let the rack run alone that long first, so that a virtual
    run begins at the simulated time a rehearsal against a served rack began. The run
    starts here: the garbage collector the script deferred is on again from here
    (laboratory.startup), whether or not the connection is made.
    """
    try:
        return _connect(lab, cfg, links_dir, rack_hook, start_s, timeout)
    finally:
        startup.resume()


def _connect(lab: Laboratory, cfg: Any, links_dir: Path | None,
             rack_hook: Callable[[Any], None] | None, start_s: float,
             timeout: float) -> Connection:
    if links_dir is None and not lab.simulated(cfg):  # the real laboratory: real time, no truth
        if start_s or rack_hook is not None:
            raise ValueError("start_s and rack_hook are for simulated racks only")
        clock: Clock = WallClock()
        return Connection(open_station(lab, cfg, lab.links(cfg, None), clock, timeout),
                          None, None, None)
    if links_dir is None:
        rack = lab.build_rack(cfg, None)
        try:
            if rack_hook is not None:
                rack_hook(rack)
            from station.clock import VirtualClock

            st = open_station(lab, cfg, lab.links(cfg, rack), VirtualClock(rack.env), timeout)
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
    # the served rack's modules on this path only: a virtual run spends none of their
    # import (pydantic models built at import, 4-5 ms of a day's; issue 17)
    from station.hil.profile import attach

    served = attach(links_dir, lab.name, lab.seed_of(cfg), lab.digest(cfg))
    st = open_station(lab, cfg, served_links(lab, served, links_dir), served.clock, timeout)
    twin = None
    if served.truth:
        try:
            twin = lab.build_rack(cfg, None)
        except BaseException:
            st.close()
            raise
    return Connection(st, None, twin, served)


def served_session(records: list[dict]) -> str | None:
    """The served rack's session of a CIGTF or ESG journal's last start (None: virtual)."""
    starts = [r for r in records if r.get("event") == "start"]
    served = starts[-1].get("served") if starts else None
    return served.get("session") if isinstance(served, dict) else None


@contextmanager
def journaled_run(out: Path, conn: Connection, resume: bool = False,
                  renew: tuple[str, ...] = (), sheet_models: Any = None,
                  identify: Identifying | None = None, **start: Any
                  ) -> Iterator[tuple[Run, dict, float]]:
    """The journal and Run of a run on ``conn``: ``(run, served_record, t_start)``; the
    start note carries ``start`` and the served rack's record; the journal and the
    connection are closed however the run ends. ``t_start`` is 0 in virtual time and the
    rack's time when served. ``resume``: the journal in ``out`` is continued, replayed in
    virtual time (each step checked against it), with its completed blocks restored over
    links; ``renew`` names the blocks a restarted rack (another session) must repeat even
    if completed (a warm-up). ``identify``: the run's identity (run.json, config.toml) is
    written around it and its run_uid goes in the start note."""
    st, served = conn.drivers, conn.served
    try:
        with opened_journal(out, resume) as journal, ExitStack() as stack:
            stack.callback(report_after, out)  # after run.json closes; not for a refused run
            stack.callback(index_after, out)  # history: after run.json closes
            kw: dict[str, Any] = {} if sheet_models is None else {"sheet_models": sheet_models}
            if identify is not None:
                doc, station_id, unit = identify.config()
                ident = stack.enter_context(identified(
                    out, identify.laboratory, identify.command, identify.seed, doc,
                    station_id, unit, resume, journal.records))
                start = {"run_uid": ident.run_uid, **start}
                kw["header"] = ident.header(f"{identify.command} (station {identify.command})")
            now = served.session.session if served is not None else None
            renewed = renew if resume and now != served_session(journal.records) else ()
            run = Run(st.clock, journal, resume="replay" if served is None else "skip",
                      repeat=renewed, **kw)
            if resume:
                resume_note(run)
            t_start = st.clock.now()
            extra = {} if served is None else {"served": served.record()}
            run.note(event="start", **start, **extra)
            yield run, extra, t_start
    finally:
        conn.close()
