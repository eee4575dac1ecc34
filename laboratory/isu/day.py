"""`station day`: the full virtual calibration day, its record and its display.

Builds the simulated rack (or, with links to a served rack or hardware, only the drivers),
runs the procedures of procedures.isu.day with a journal in DIR, then writes the sheets,
results.json (estimate, truth, error and predicted sigma side by side) and the plots.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path

from rich import box
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn
from rich.table import Table

from laboratory.connect import Connection, connect
from laboratory.isu.lab import LAB
from laboratory.isu.plots import nonlinearity_plot
from laboratory.isu.truth import calibration_truth
from laboratory.record import write_results, write_sheets
from laboratory.rundir import opened_journal, prepare, resume_note
from procedures.isu.calibration import NoiseSpec
from procedures.isu.computations import compute_calibration
from procedures.isu.day import EXPERIMENTS, measure_day
from procedures.isu.plan import DayPlan
from procedures.isu.sheets import ISU_SHEETS
from procedures.journal import Journal
from procedures.runner import Run
from sim import units
from station.config.isu import StationConfig
from station.files import atomic_path
from station.racks.isu import SimulatedRack

EXPECTED_SIM_S = 9.0 * 3600.0  # for the progress bar only


def site_info(cfg: StationConfig) -> dict:
    """Current laboratory survey information (Chart I-2 step 3) from the station config."""
    lat = math.radians(cfg.site.latitude_deg)
    w = cfg.site.earth_rate_deg_per_hr
    return {
        "g": cfg.site.g_local_mps2 / units.G0,
        "omega_sin_lambda": w * math.cos(lat),  # lambda = colatitude: north component
        "omega_cos_lambda": w * math.sin(lat),  # vertical component
    }


class DayDisplay:
    """Check-sheet ticks as they happen, and a progress bar in simulated time."""

    def __init__(self, console: Console, quiet: bool = False) -> None:
        self.console = console
        self.quiet = quiet
        self.progress = Progress(
            TextColumn("[bold]{task.description}"), BarColumn(),
            TextColumn("{task.fields[sim]}"), console=console, transient=True,
        )
        self.task = self.progress.add_task("calibration day", total=EXPECTED_SIM_S, sim="")

    def __enter__(self) -> DayDisplay:
        if not self.quiet:
            self.progress.start()
        return self

    def __exit__(self, *exc) -> None:
        if not self.quiet:
            self.progress.stop()

    def __call__(self, ev: dict) -> None:
        if self.quiet:
            return
        kind = ev.get("kind")
        if kind == "sheet_start":
            self.progress.console.print(f"[bold cyan]Chart {ev['chart']}[/]  {ev['title']}")
        elif kind == "step":
            t = ev["t_sim"]
            self.progress.console.print(
                f"  [green]\u2713[/] [dim]{t / 3600:6.3f} h[/] {ev['chart']:>6} "
                f"{ev['step']:<12} {ev['text'][:48]}", highlight=False, no_wrap=True,
                overflow="ellipsis",
            )
            self.progress.update(self.task, completed=min(t, EXPECTED_SIM_S),
                                 sim=f"{t / 3600:5.2f} h simulated")


def results_rows(calib, truth: dict) -> list[dict]:
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
    t = Table(title="Calibration Results Sheet (Chart II-5)", box=box.SIMPLE_HEAD,
              pad_edge=False, collapse_padding=True)
    for c in ("inst", "param", "units", "estimate", "truth", "error", "sigma", "err/sig"):
        t.add_column(c, justify="left" if c in ("inst", "param", "units") else "right",
                     no_wrap=True)
    for r in rows:
        def g(x, fmt):
            return "-" if x is None else format(x, fmt)
        z = None
        if r["error"] is not None and r["sigma"]:
            z = r["error"] / r["sigma"]
        zs = "-" if z is None else (f"[red]{z:+.2f}[/]" if abs(z) > 4 else f"{z:+.2f}")
        est = g(r["estimate"], ".8g") if r["estimate"] is not None else "[dim]not determined[/]"
        t.add_row(r["instrument"], r["parameter"], r["units"], est, g(r["truth"], ".8g"),
                  g(r["error"], ".2e"), g(r["sigma"], ".2e"), zs)
    console.print(t)


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


def run_day(cfg: StationConfig, out: Path, only: tuple[str, ...] | None = None,
            resume: bool = False, console: Console | None = None, quiet: bool = False,
            plan: DayPlan | None = None,
            rack_hook: Callable[[SimulatedRack], None] | None = None,
            align: bool = True, links: Path | None = None,
            positions: tuple[int, ...] | None = None, start_s: float = 0.0) -> dict:
    """Run the day into ``out``; ``rack_hook`` may inject faults into the simulated rack.

    After the calibration the three alignments of Part III run (``align=False`` skips them).
    ``links``: run over the links of a rack served under that directory (real time); a
    resume then restores the completed charts instead of replaying them, and repeats
    turn-on if the rack was restarted meanwhile. ``start_s`` (virtual): begin at that
    simulated time, to compare with a rehearsal that began then. ``out`` must hold no
    record unless ``resume`` (RunDirError); nothing is written before the checks pass.
    """
    console = console or Console()
    plan = plan or DayPlan()
    out = Path(out)
    check_selection(only, positions)
    prepare(out, resume, links)
    wall0 = time.perf_counter()
    conn = connect(LAB, cfg, links, rack_hook, start_s)
    try:
        with opened_journal(out, resume) as journal:
            return _day(cfg, out, conn, journal, only, resume, console, quiet, plan, align,
                        links, positions, wall0)
    finally:
        conn.close()


def _day(cfg: StationConfig, out: Path, conn: Connection, journal: Journal,
         only: tuple[str, ...] | None, resume: bool, console: Console, quiet: bool,
         plan: DayPlan, align: bool, links: Path | None, positions: tuple[int, ...] | None,
         wall0: float) -> dict:
    st = conn.station
    sid = conn.session.session if conn.session else None
    repeat = ("I-1",) if resume and sid != rack_session(journal) else ()
    with DayDisplay(console, quiet) as display:
        run = Run(st.clock, journal, listener=display,
                  resume="replay" if conn.rack is not None else "skip", repeat=repeat,
                  sheet_models=ISU_SHEETS)
        if resume:
            resume_note(run)
        run.note(event="start", t_sim=st.clock.now(), seed=cfg.seed,
                 only=list(only or ()), resume=resume,
                 positions=list(positions or ()), session=sid,
                 links=None if links is None else str(links))
        data = measure_day(st, run, plan, site_info(cfg), cfg.isu.accels[0].f0_hz, only,
                           positions, noise=noise_spec(cfg))
        calib = compute_calibration(run, data, plan, noise_spec(cfg), site_info(cfg))
        alignment = []
        if align and data.survey is not None:
            from laboratory.isu.align import day_alignments

            alignment = day_alignments(st, run, calib, cfg, conn.attitude_world,
                                       tape_dir=out / "tapes")
    write_sheets(out, run)
    with atomic_path(out / "nonlinearity.png") as tmp:
        nonlinearity_plot(data.nonlinearity, tmp)
    world = conn.coefficient_world
    rows = results_rows(calib, calibration_truth(world) if world else {})
    res = {
        "seed": cfg.seed,
        "sim_seconds": st.clock.now(),
        "wall_seconds": time.perf_counter() - wall0,
        "calibration": rows,
        "alignment": alignment,
        "links": None if links is None else str(links),
        "restored_charts": run.restored,
    }
    write_results(out, res)
    run.note(event="end", sim_seconds=st.clock.now())
    if not quiet:
        render_results(console, rows)
        if alignment:
            from laboratory.isu.align import render_alignment

            render_alignment(console, alignment)
    return res


def noise_spec(cfg: StationConfig) -> NoiseSpec:
    """The laboratory's noise specification (what the error model of II-4 assumes)."""
    g = cfg.isu.gyros[0]
    a = cfg.isu.accels[0]
    env = cfg.environment
    tb = cfg.table
    ins = cfg.instruments
    return NoiseSpec(
        gyro_arw_deg_rt_hr=g.arw_deg_rt_hr,
        gyro_drift_sigma_deg_hr=g.drift_sigma_deg_hr,
        gyro_drift_tau_s=g.drift_tau_s,
        gyro_sample_rate_hz=g.pulse_rate_hz,
        accel_white_micro_g_rt_hz=a.noise_micro_g_rt_hz,
        vibration_rms_micro_g=env.vibration.rms_micro_g,
        vibration_band_hz=tuple(env.vibration.band_hz),
        bubble_noise_arcsec=ins.bubble_level.noise_arcsec,
        bubble_graduation_arcsec=ins.bubble_level.resolution_arcsec,
        table_setting_arcsec=tb.setting_noise_arcsec,
        resolver_cyclic_arcsec=tb.resolver_error_arcsec,
        nonorthogonality_arcsec=tb.nonorthogonality_arcsec,
        autocollimator_arcsec=ins.autocollimator.noise_arcsec,
        tilt_diurnal_pp_arcsec=env.pier_tilt.diurnal_pp_arcsec,
        tilt_diurnal_azimuth_deg=env.pier_tilt.diurnal_azimuth_deg,
        tilt_wander_sigma_arcsec=env.pier_tilt.wander_sigma_arcsec,
        tilt_wander_tau_s=env.pier_tilt.wander_tau_s,
        wobble_amplitude_arcsec=env.wobble.amplitude_arcsec,
        wobble_period_s=env.wobble.period_s,
        wobble_coherence_s=env.wobble.coherence_s,
    )
