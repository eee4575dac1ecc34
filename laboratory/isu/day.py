"""`station day`: the full virtual calibration day, its record and its display.

Builds the simulated rack (or, with links to a served rack or hardware, only the drivers),
runs the procedures of procedures.isu.day with a journal in DIR, then writes the sheets,
results.json (estimate, truth, error and predicted sigma side by side) and the plots.
``DayRequest`` says what to run, where and how; ``run_day`` runs it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

from laboratory import registry
from laboratory.calfile import FILE_NAME as CALIBRATION_FILE
from laboratory.calfile import day_calibration_document
from laboratory.connect import Connection, connect
from laboratory.export import can_log, write_results_csv
from laboratory.history import index_after
from laboratory.identity import RunIdentity, identified, isu_config, isu_identity
from laboratory.isu.align import day_alignments, render_alignment, tape_library
from laboratory.isu.display import DayDisplay, shown_console
from laboratory.isu.plot_child import DAY_CHILD, PLOTS
from laboratory.isu.prior import CarriedSheets, carried_sheets
from laboratory.isu.spec import mounting, noise_spec, site_of
from laboratory.isu.truth import calibration_truth
from laboratory.plot_worker import PlotWorker
from laboratory.record import (
    SHEET_STAGE,
    Blobs,
    sheet_blobs,
    sheet_values,
    write_results,
    write_sheet_values,
)
from laboratory.report import report_after
from laboratory.report.html import PREPARE_JOB
from laboratory.rundir import opened_journal, prepare, resume_note
from laboratory.shown import Shown
from laboratory.tables import Column, print_fitted
from laboratory.verdicts import judge_constants, run_verdict
from procedures.isu.alignment.results_sheet import AlignPlan
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.computations import compute_calibration
from procedures.isu.day import EXPERIMENTS, chart_data, measure_day
from procedures.isu.plan import DayPlan
from procedures.isu.settings import collection_times
from procedures.isu.sheets import (
    ISU_SHEETS,
    CalibrationResults,
)
from procedures.journal import Journal
from procedures.runner import Run
from station.config.isu import StationConfig
from station.files import clear_prefixed
from station.racks.isu import SimulatedRack

if TYPE_CHECKING:  # rich.console imported when a console shows something (issue 17)
    from rich.console import Console


@dataclass(frozen=True)
class DayRequest:
    """One `station day` run: what to measure, where to record it and how to run it.

    ``cfg``: the station config (its seed is the run's; its ``[plan]`` gives the required
    accuracies, which set the collection times). ``out``: the run directory (it must
    hold no record unless ``resume``). ``only`` / ``positions``: measure only these charts /
    calibration positions (turn-on and survey always run). ``plan``: the day's required
    accuracies and operator choices. ``align``: run the three alignments of Part III after
    the calibration, with ``align_plan`` (None: the config's ``[alignment]``), taking and
    filing tapes in ``tape_library`` (None: the config's, if any). ``links``: run over the
    links of a rack served under that directory (real time); a resume then restores the
    completed charts instead of replaying them, and repeats turn-on if the rack was
    restarted meanwhile. ``start_s``
    (virtual): begin at that simulated time, to compare with a rehearsal that began then.
    ``quiet``: no live display. ``prior`` / ``survey``: an earlier run whose Calibration /
    Survey Results Sheet this run carries forward (laboratory.isu.prior checks its unit and
    age). An unknown chart or position is refused here (ValueError).
    """

    cfg: StationConfig
    out: Path
    only: tuple[str, ...] | None = None
    positions: tuple[int, ...] | None = None
    resume: bool = False
    links: Path | None = None
    start_s: float = 0.0
    plan: DayPlan = field(default_factory=DayPlan)
    align: bool = True
    align_plan: AlignPlan | None = None
    tape_library: Path | None = None
    quiet: bool = False
    prior: Path | None = None
    survey: Path | None = None

    def __post_init__(self) -> None:
        check_selection(self.only, self.positions)
        # frozen: normalised through object.__setattr__ (tuples, so the request is a value)
        object.__setattr__(self, "out", Path(self.out))
        for name in ("only", "positions"):
            v = getattr(self, name)
            object.__setattr__(self, name, None if v is None else tuple(v))
        for name in ("prior", "survey"):
            v = getattr(self, name)
            object.__setattr__(self, name, None if v is None else Path(v))


def results_rows(calib: CalibrationResults, truth: dict[tuple[str, str], float]
                 ) -> list[dict]:
    rows = []
    for r in calib.rows:
        tv = truth.get((r.instrument, r.parameter))
        err = None if r.estimate is None or tv is None else r.estimate - tv
        rows.append({
            "instrument": r.instrument, "parameter": r.parameter, "units": r.units,
            "estimate": r.estimate, "truth": tv, "error": err, "sigma": r.sigma,
            "positions": r.positions, "note": r.note,
        })
    return rows


def render_results(console: Console, rows: list[dict]) -> None:
    """Chart II-5's rows on the console; split into narrower tables rather than cut a
    number when the console is narrow (limit and verdict shown when the rows carry them)."""
    judged = any("verdict" in r for r in rows)
    names = ["inst", "param", "units", "estimate", "sigma"]
    names += ["limit", "verdict"] if judged else []
    names += ["truth", "error", "err/sig"]
    cols = [Column(c, right=c not in ("inst", "param", "units", "verdict")) for c in names]

    def g(x: float | None, fmt: str) -> str:
        return "-" if x is None else format(x, fmt)

    cells = []
    for r in rows:
        z = None
        if r["error"] is not None and r["sigma"]:
            z = r["error"] / r["sigma"]
        zs = "-" if z is None else (f"[red]{z:+.2f}[/]" if abs(z) > 4 else f"{z:+.2f}")
        est = g(r["estimate"], ".8g") if r["estimate"] is not None else "[dim]not determined[/]"
        row = [r["instrument"], r["parameter"], r["units"], est, g(r["sigma"], ".2e")]
        if judged:
            v = str(r.get("verdict") or "-")
            row += [g(r.get("limit"), ".3g"), f"[red]{v}[/]" if v == "FAIL" else v]
        row += [g(r["truth"], ".8g"), g(r["error"], ".2e"), zs]
        cells.append(row)
    print_fitted(console, "Calibration Results Sheet (Chart II-5)", cols, cells)


class NonlinearityPlot:
    """The nonlinearity plot, sent to the plot child as soon as Chart II-7's block has run
    (its data are the block's, as measure_day loads them), so that the child draws it
    while the positions go on and is free for the computations' fit and the results plot
    (issue 17); else (II-7 restored or not measured) once the measurements end."""

    def __init__(self, plotter: PlotWorker, noise: NoiseSpec, path: Path) -> None:
        self.plotter, self.noise, self.path = plotter, noise, path
        self.sent = False

    def chart_done(self, ev: dict) -> None:
        if ev.get("kind") == "block" and ev.get("key") == "II-7":
            self.send(chart_data(ev["data"]))

    def send(self, points: dict[int, list[dict]]) -> None:
        if not self.sent:
            self.sent = True
            self.plotter.draw([(f"{PLOTS}:nonlinearity_plot", {
                "points": points, "noise": self.noise, "path": self.path})], more=True)


class SheetsRendered:
    """The sheets' files rendered by the plot child while the alignments run, kept there
    for ``sheets_beside``, which writes them unless a sheet changed since (issue 17: 0.05 s
    of indented JSON off the end of the day). ``start``: those the run holds now (the
    calibration's), after the plots sent before; then each sheet as it is saved (as a
    listener). Only after the computations' fit has been sent: nothing here delays it.
    Nothing is written here."""

    def __init__(self, plotter: PlotWorker, out: Path) -> None:
        self.plotter, self.out, self.started = plotter, out, False

    def start(self, run: Run) -> None:
        self.started = True
        self._send(sheet_blobs(run.sheets))

    def __call__(self, ev: dict) -> None:
        if self.started and ev.get("kind") == "sheet":
            self._send(sheet_blobs({str(ev["name"]): ev["data"]}))

    def _send(self, blobs: Blobs | None) -> None:
        if blobs:
            self.plotter.compute("laboratory.record:render_sheet_blobs",
                                 {"out": self.out, "blobs": blobs})


def sheets_beside(plotter: PlotWorker, out: Path, run: Run) -> Callable[[], None]:
    """The sheets' files written by the plot child (most of them staged there during the
    alignments, ``SheetsRendered``: renamed into place), while this process writes the
    rest of the record (issue 17); here, now, when pickle cannot carry a sheet. Call the
    result before the plots are waited for (``PlotWorker.wait`` forgets its jobs): it
    returns once they are written (here, on the sheets as they were, if the child did
    not)."""
    blobs = sheet_blobs(run.sheets)
    if blobs is not None:
        return plotter.compute("laboratory.record:write_sheet_blobs",
                               {"out": out, "blobs": blobs})
    write_sheet_values(out, sheet_values(run))
    return lambda: None


def rack_session(journal: Journal) -> str | None:
    """The served rack's session the journal's last run talked to (None: virtual)."""
    starts = [r for r in journal.records if r.get("event") == "start"]
    return starts[-1].get("session") if starts else None


def check_selection(only: tuple[str, ...] | None, positions: tuple[int, ...] | None) -> None:
    """ValueError naming the unknown charts or positions of ``--only`` / ``--positions``
    (before anything is opened; measure_day checks the same again)."""
    unknown = sorted(set(only or ()) - set(EXPERIMENTS) - {"I-1", "I-2"})
    if unknown:
        raise ValueError(f"--only: unknown chart(s) {', '.join(unknown)}; choose from "
                         f"{', '.join(EXPERIMENTS)}")
    bad = sorted(set(positions or ()) - set(range(1, 16)))
    if bad:
        raise ValueError(f"--positions: unknown position(s) {', '.join(map(str, bad))}; "
                         "calibration positions are 1 to 15")


def day_plan(req: DayRequest) -> DayPlan:
    """The request's operator choices with the config's required accuracies (``[plan]``)
    and options (``[calibration]``, when given)."""
    options = {} if req.cfg.calibration is None else {"options": req.cfg.calibration}
    return req.plan.model_copy(update={"requirements": req.cfg.plan, **options})


def check_plan(cfg: StationConfig, plan: DayPlan) -> None:
    """ValueError (procedures.isu.accuracy.Unreachable) naming a required accuracy that no
    admissible gate reaches, before anything is opened (the day's II-6 settings give the
    same times from the measured clock period)."""
    collection_times(plan, site_of(cfg), noise_spec(cfg), f0=cfg.isu.accels[0].f0_hz,
                     t_bi=mounting(cfg))


def run_day(req: DayRequest, console: Console | None = None,
            rack_hook: Callable[[SimulatedRack], None] | None = None) -> dict:
    """Run the day ``req`` asks for into ``req.out``; returns the results (also
    ``results.json``). ``rack_hook`` may inject faults into the simulated rack.

    After the calibration the three alignments of Part III run (``req.align`` False skips
    them). ``req.out`` must hold no record unless ``req.resume`` (RunDirError); nothing is
    written before the checks pass.
    """
    console = shown_console(console, req.quiet)
    carried = carried_sheets(req.cfg, req.prior, req.survey)  # refused before anything
    req = replace(req, plan=day_plan(req))
    check_plan(req.cfg, req.plan)  # an unreachable requirement: refused before anything
    prepare(req.out, req.resume, req.links)
    wall0 = time.perf_counter()
    conn = connect(registry.get("isu"), req.cfg, req.links, rack_hook, req.start_s)
    try:
        with opened_journal(req.out, req.resume) as journal, ExitStack() as stack:
            # the plot child (importing matplotlib meanwhile) outlives the record: it
            # compiles the report's template when idle and writes the report at the end
            stack.callback(clear_prefixed, req.out, SHEET_STAGE)  # after the child ends
            plotter = stack.enter_context(PlotWorker(*DAY_CHILD))
            plotter.compute(PREPARE_JOB, {})
            # report.html of what the record holds, however it ended: after run.json is
            # closed, while this run still holds the directory (a refused run writes none)
            stack.callback(report_after, req.out, plotter)
            stack.callback(index_after, req.out)  # history: after run.json closes
            ident = stack.enter_context(identified(
                req.out, "isu", "day", req.cfg.seed, isu_config(req.cfg),
                *isu_identity(req.cfg), req.resume, journal.records))
            return _day(req, conn, journal, console, wall0, ident, carried, plotter)
    finally:
        conn.close()


def _day(req: DayRequest, conn: Connection, journal: Journal, console: Console | None,
         wall0: float, ident: RunIdentity, carried: CarriedSheets, plotter: PlotWorker) -> dict:
    cfg, out, links = req.cfg, req.out, req.links
    st = conn.station
    sid = conn.session.session if conn.session else None
    repeat = ("I-1",) if req.resume and sid != rack_session(journal) else ()
    site, noise = site_of(cfg), noise_spec(cfg)
    with can_log(out, st.ieu), DayDisplay(console) as display:
        nonlinearity = NonlinearityPlot(plotter, noise, out / "nonlinearity.png")
        rendered = SheetsRendered(plotter, out)

        def listener(ev: dict) -> None:
            display(ev)
            nonlinearity.chart_done(ev)
            rendered(ev)

        run = Run(st.clock, journal, listener=listener,
                  resume="replay" if conn.rack is not None else "skip", repeat=repeat,
                  sheet_models=ISU_SHEETS, sheets_used=carried.sheets_used, beside=plotter,
                  header=ident.header("calibration day (station day)",
                                      ident.record["unit"]["isu"]))
        if req.resume:
            resume_note(run)
        run.note(event="start", run_uid=ident.run_uid, t_sim=st.clock.now(), seed=cfg.seed,
                 only=list(req.only or ()), resume=req.resume,
                 positions=list(req.positions or ()), session=sid,
                 require=[f"{k}={v!r}" for k, v in cfg.plan.model_dump().items()],
                 links=None if links is None else str(links), **carried.note())
        data = measure_day(st, run, req.plan, site, cfg.isu.accels[0].f0_hz, req.only,
                           req.positions, noise=noise, survey=carried.survey)
        nonlinearity.send(data.nonlinearity)  # unless Chart II-7's block was run and sent
        calib = compute_calibration(run, data, req.plan, noise, site, prior=carried.prior)
        world = conn.coefficient_world
        rows = judge_constants(results_rows(calib, calibration_truth(world) if world else {}),
                               cfg.limits)
        plotter.draw([  # drawn during the alignments; waited for before the end note
            (f"{PLOTS}:results_plot", {"rows": rows, "path": out / "results.png"}),
            # calibration.json written beside too, its JSON and sync off the day's end
            ("laboratory.record:write_json", {"path": out / CALIBRATION_FILE, "sync_dir": False,
                                             "obj": day_calibration_document(
                                                 out, calib, cfg, data, req.plan, site, noise)})],
            more=True)  # the sheets may follow
        rendered.start(run)
        alignment = []
        if req.align and data.survey is not None:
            alignment = day_alignments(st, run, calib, cfg, conn.attitude_world,
                                       tape_dir=out / "tapes", plan=req.align_plan,
                                       samples_dir=out,
                                       library=tape_library(cfg, req.tape_library,
                                                            ident.run_uid))
    sheets = sheets_beside(plotter, out, run)
    res = {
        "seed": cfg.seed,
        "sim_seconds": st.clock.now(),
        "wall_seconds": time.perf_counter() - wall0,
        "calibration": rows,
        "alignment": alignment,
        "links": None if links is None else str(links),
        "restored_charts": run.restored,
        "verdict": run_verdict(rows, alignment),
    }
    write_results(out, res)
    write_results_csv(out, rows)
    if alignment:
        write_results_csv(out, alignment, "alignment.csv")

    def show(res: dict) -> None:
        assert console is not None  # shown only with a console (not quiet)
        render_results(console, res["calibration"])
        if res["alignment"]:
            render_alignment(console, res["alignment"])

    shown = Shown(None if console is None else show, prepare=False)  # the child has the template

    def meanwhile() -> None:
        shown.meanwhile(res)
        sheets()  # written by the child, or here if it did not (the run's error then)

    plotter.wait(meanwhile=meanwhile, keep=True)  # the child writes the report later
    run.note(event="end", sim_seconds=st.clock.now())
    shown.done(res)  # or its error, as when the display followed the end note
    return res
