"""Command line: `station check`, and the procedure commands as they are added."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from station.config import ConfigError, load_config

app = typer.Typer(add_completion=False, no_args_is_help=True, help="The simulated ISU laboratory.")
console = Console() if Console().is_terminal else Console(width=110)

ConfigOpt = Annotated[
    Path | None, typer.Option("--config", help="station config TOML (merged over the default)")
]
SeedOpt = Annotated[int | None, typer.Option("--seed", help="run seed (default: the config's)")]


@app.callback()
def _root() -> None:
    """The simulated ISU laboratory: checks, procedures and rehearsals."""


def _load(config: Path | None, seed: int | None = None):
    try:
        return load_config(config, seed=seed)
    except ConfigError as e:
        console.print(f"[red]{e}[/red]")
        raise typer.Exit(2) from None


@app.command()
def check(
    config: ConfigOpt = None,
    as_json: Annotated[bool, typer.Option("--json", help="print the results as JSON")] = False,
    timeout: Annotated[float, typer.Option(help="reply timeout per instrument, s")] = 2.0,
    links: Annotated[Path | None, typer.Option("--links", help="check the rack served under "
                     "this directory instead")] = None,
) -> None:
    """Talk to every instrument over its configured link; exit 1 naming any that does not answer."""
    from station.check import as_dicts, check_all

    cfg = _load(config)
    if links is not None:
        from station.connect import served_config
        from station.hil.profile import attach
        from station.hil.session import config_digest

        try:
            cfg = served_config(cfg, attach(links, "isu", cfg.seed, config_digest(cfg)))
        except (ValueError, FileNotFoundError) as e:
            console.print(f"[red]error:[/red] {e}")
            raise typer.Exit(2) from None
    results = check_all(cfg, timeout)
    if as_json:
        typer.echo(json.dumps(as_dicts(results), indent=2))
    else:
        t = Table(title="Instrument check")
        for col in ("instrument", "link", "ok", "identity / error"):
            t.add_column(col)
        for r in results:
            t.add_row(
                r.instrument, r.link, "[green]yes[/green]" if r.ok else "[red]NO[/red]", r.identity
            )
        console.print(t)
    bad = [r.instrument for r in results if not r.ok]
    if bad:
        typer.echo(f"not answering: {', '.join(bad)}", err=True)
        raise typer.Exit(1)


LinksOpt = Annotated[Path | None, typer.Option(
    "--links", help="run over the links of a rack served under this directory "
    "(station serve --links DIR), in real time")]


@app.command()
def day(
    config: ConfigOpt = None,
    seed: SeedOpt = None,
    out: Annotated[Path, typer.Option("--out", help="run directory")] = Path("runs/day"),
    only: Annotated[list[str] | None, typer.Option("--only", help="measure only these charts "
                    "(II-6, II-7, II-7Q, II-10, II-11..II-14); repeatable")] = None,
    positions: Annotated[list[int] | None, typer.Option("--positions", help="only these "
                         "calibration positions (1-15; a pair m, m+1 is measured whole); "
                         "repeatable")] = None,
    resume: Annotated[Path | None, typer.Option("--resume", help="continue the interrupted "
                      "run in this directory")] = None,
    links: LinksOpt = None,
    start_at: Annotated[float, typer.Option("--start-at", help="virtual run: begin at this "
                        "simulated time, s (to compare with a rehearsal that began then)")
                        ] = 0.0,
    quiet: Annotated[bool, typer.Option("--quiet", help="no live display")] = False,
) -> None:
    """The full calibration day: turn-on, survey, positions 1-15, computations, alignments.

    Virtual time by default; with --links, in real time against a served rack (or hardware).
    """
    from procedures.runner import ProcedureError, ResumeMismatch
    from station.day_cmd import run_day
    from station.errors import StationError

    cfg = _load(config, seed)
    target = resume if resume is not None else out
    try:
        res = run_day(cfg, target, tuple(only) if only else None, resume is not None,
                      console, quiet, links=links,
                      positions=tuple(positions) if positions else None, start_s=start_at)
    except (ValueError, FileNotFoundError) as e:  # bad charts/positions, nothing served
        console.print(f"[red]error:[/red] {e}")
        raise typer.Exit(2) from None
    except (ProcedureError, ResumeMismatch, StationError) as e:
        console.print(f"[red]stopped:[/red] {e}")
        console.print(f"the journal keeps every completed step: {target / 'journal.jsonl'}")
        raise typer.Exit(1) from None
    console.print(
        f"{res['sim_seconds'] / 3600:.2f} h simulated in {res['wall_seconds']:.1f} s; "
        f"record in {target}"
    )


@app.command()
def align(
    method: Annotated[str, typer.Option("--method", help="mirror | level | gyrocompass")],
    estimator: Annotated[str, typer.Option("--estimator", help="average | posterior | "
                         "hybrid")] = "average",
    calibration: Annotated[Path | None, typer.Option("--calibration", help="run directory "
                           "whose Calibration Results Sheet to use (default: calibrate "
                           "first)")] = None,
    config: ConfigOpt = None,
    seed: SeedOpt = None,
    out: Annotated[Path, typer.Option("--out", help="run directory")] = Path("runs/align"),
    links: LinksOpt = None,
    quiet: Annotated[bool, typer.Option("--quiet", help="no live display")] = False,
) -> None:
    """One alignment (Part III): mirror, level or gyrocompass, with the chosen estimator."""
    from procedures.runner import ProcedureError
    from station.align_cmd import run_align
    from station.errors import StationError

    if method not in ("mirror", "level", "gyrocompass"):
        console.print(f"[red]unknown method {method!r}: mirror, level or gyrocompass[/red]")
        raise typer.Exit(2)
    if estimator not in ("average", "posterior", "hybrid"):
        console.print(f"[red]unknown estimator {estimator!r}: average, posterior or "
                      "hybrid[/red]")
        raise typer.Exit(2)
    cfg = _load(config, seed)
    try:
        res = run_align(cfg, out, method, estimator, calibration, console=console,
                        quiet=quiet, links=links)
    except (ProcedureError, StationError, FileNotFoundError, ValueError) as e:
        console.print(f"[red]stopped:[/red] {e}")
        raise typer.Exit(1) from None
    console.print(f"{res['sim_seconds'] / 3600:.2f} h simulated in {res['wall_seconds']:.1f} s;"
                  f" record in {out}")


@app.command()
def serve(
    config: ConfigOpt = None,
    seed: SeedOpt = None,
    speed: Annotated[float, typer.Option("--speed", help="simulated seconds per wall "
                     "second")] = 1.0,
    links: Annotated[Path, typer.Option("--links", help="directory for the pty symlinks "
                     "and links.json")] = Path("runs/links"),
    only: Annotated[list[str] | None, typer.Option("--only", help="serve only these "
                    "instruments; repeatable")] = None,
    can_port: Annotated[int, typer.Option("--can-port", help="socketcand TCP port (0: any "
                        "free port)")] = 0,
    station: Annotated[str, typer.Option("--station", help="which rack: isu (default), "
                       "cigtf (gyrocompass fixture, [cigtf] config, seed 1 unless given) or "
                       "esg ([esg] config, seed 1 unless given)")] = "isu",
) -> None:
    """Serve a simulated rack in real time on ptys (the ISU's IEU also on socketcand and
    slcan), with a live status table; stop with Ctrl-C."""
    from station.hil.server import STATIONS, load_station
    from station.hil.server import serve as serve_rack

    if speed <= 0:
        console.print("[red]--speed must be > 0[/red]")
        raise typer.Exit(2)
    if station not in STATIONS:
        console.print(f"[red]unknown station {station!r}: {', '.join(STATIONS)}[/red]")
        raise typer.Exit(2)
    try:
        target = load_station(station, config, seed)
    except ConfigError as e:
        console.print(f"[red]{e}[/red]")
        raise typer.Exit(2) from None
    try:
        serve_rack(target, speed, links, only or None, can_port=can_port)
    except (ValueError, OSError) as e:
        console.print(f"[red]{e}[/red]")
        raise typer.Exit(2) from None
    except RuntimeError as e:
        console.print(f"[red]{e}[/red]")
        raise typer.Exit(1) from None


@app.command()
def compare(
    dir_a: Path,
    dir_b: Path,
    rel_tol: Annotated[float, typer.Option(help="ignore relative differences up to this")] = 0.0,
    rehearsal: Annotated[bool, typer.Option("--rehearsal", help="DIR_A is a run over links, "
                         "DIR_B its virtual twin: compare within the real-time tolerances "
                         "(docs/hil.md)")] = False,
) -> None:
    """Show which sheet and result values differ between two run directories."""
    from station.compare import differences

    if rehearsal:
        from station.hil.twin import compare_rehearsal

        try:
            problems = compare_rehearsal(dir_a, dir_b)
        except (FileNotFoundError, ValueError) as e:
            console.print(f"[red]{e}[/red]")
            raise typer.Exit(2) from None
        for line in problems:
            console.print(line)
        console.print("equal within the real-time tolerances" if not problems
                      else f"{len(problems)} differences beyond the tolerances")
        raise typer.Exit(1 if problems else 0)
    try:
        diffs = differences(dir_a, dir_b, rel_tol)
    except FileNotFoundError as e:
        console.print(f"[red]{e}[/red]")
        raise typer.Exit(2) from None
    if not diffs:
        console.print("no differences")
        return
    t = Table(title=f"{len(diffs)} values differ")
    for c in ("where", str(dir_a), str(dir_b)):
        t.add_column(c)
    for k, a, b in diffs:
        t.add_row(k, str(a), str(b))
    console.print(t)
    raise typer.Exit(1)


def _station_run(load_params, config: Path | None, out: Path, unit: str, run):
    """Load a station's params from ``config`` and ``run(params)``: exit 2 on a bad config
    or a missing or wrong served rack, 1 when a step fails (the journal keeps every
    completed ``unit``)."""
    from procedures.runner import ProcedureError
    from station.config import ConfigError
    from station.errors import StationError
    from station.hil.profile import NoServedRack, WrongStation

    try:
        params = load_params(config)
    except ConfigError as e:
        console.print(f"[red]{e}[/red]")
        raise typer.Exit(2) from None
    try:
        return run(params)
    except (NoServedRack, WrongStation) as e:
        console.print(f"[red]{e}[/red]")
        raise typer.Exit(2) from None
    except (ProcedureError, StationError) as e:
        console.print(f"[red]stopped:[/red] {e}")
        console.print(f"the journal keeps every completed {unit}: {out / 'journal.jsonl'}")
        raise typer.Exit(1) from None


@app.command("gyrocompass-test")
def gyrocompass_test(
    seed: Annotated[int, typer.Option("--seed", help="run seed")] = 1,
    out: Annotated[Path, typer.Option("--out", help="run directory")] = Path("runs/gyrocompass"),
    analyse: Annotated[Path | None, typer.Option("--analyse", help="recompute the phase "
                       "analysis from the journal in this directory (e.g. after a stop)")] = None,
    config: Annotated[Path | None, typer.Option("--config", help="TOML with a [cigtf] "
                      "section (latitude_deg, noise and misalignment magnitudes)")] = None,
    links: Annotated[Path | None, typer.Option("--links", help="run against the rack "
                     "`station serve --station cigtf --links DIR` serves (real time)")] = None,
) -> None:
    """The CIGTF gyrocompassing accuracy test (report 001) on the simulated fixture."""
    from station.cigtf_cmd import analyse_journal, run_gyrocompass_test

    if analyse is not None:
        try:
            res = analyse_journal(analyse)
        except (ValueError, FileNotFoundError) as e:
            console.print(f"[red]{e}[/red]")
            raise typer.Exit(1) from None
        for p in res["phases"]:
            console.print(f"{p['phase']:>9}: theta {p['theta_arcsec']:+.2f} +/- "
                          f"{p['sigma_arcsec']:.2f} arcsec (n = {p['n']}, from the journal)")
        console.print(f"written {analyse / 'gyrocompass_analysis.json'}")
        return
    from station.cigtf_config import load_cigtf_params

    res = _station_run(load_cigtf_params, config, out, "run",
                       lambda params: run_gyrocompass_test(seed, out, params=params,
                                                           links=links))
    from station.cigtf_cmd import render_tables

    render_tables(console, res)
    for p in res["phases"]:
        console.print(f"{p['phase']:>9}: theta {p['theta_arcsec']:+.2f} +/- "
                      f"{p['sigma_arcsec']:.2f} arcsec (n = {p['n']})")
    truth = res["truth"]["theta_arcsec"]
    console.print(f"truth (eq. 26) {'absent' if truth is None else f'{truth:+.2f} arcsec'}; "
                  f"delta {res['delta_arcsec']:.2f}, Delta {res['Delta_arcsec']:.2f} arcsec")
    if "served" in res:
        console.print(f"served rack (session {res['served']['session']}): "
                      f"{res['served']['note']}")
    console.print(f"{res['sim_seconds'] / 3600:.1f} h simulated in {res['wall_seconds']:.1f} s;"
                  f" record in {out}")


@app.command("esg-calibration")
def esg_calibration(
    seed: Annotated[int, typer.Option("--seed", help="run seed")] = 1,
    out: Annotated[Path, typer.Option("--out", help="run directory")] = Path("runs/esg"),
    config: Annotated[Path | None, typer.Option("--config", help="TOML with an [esg] "
                      "section (site, rotor, [esg.pattern], [esg.signal])")] = None,
    links: Annotated[Path | None, typer.Option("--links", help="run against the rack "
                     "`station serve --station esg --links DIR` serves (real time)")] = None,
) -> None:
    """The strapdown ESG pattern calibration and readout study (report 004)."""
    from station.esg_cmd import render_tables, run_esg_calibration
    from station.esg_config import load_esg_params

    res = _station_run(load_esg_params, config, out, "step",
                       lambda params: run_esg_calibration(seed, out, params=params,
                                                          links=links))
    render_tables(console, res)
    if "served" in res:
        console.print(f"served rack (session {res['served']['session']}): "
                      f"{res['served']['note']} (pickoff-1 coning only: the true colatitudes "
                      "depend on the served rack's path and are left out)")
    console.print(f"{res['sim_seconds'] / 3600:.1f} h simulated in {res['wall_seconds']:.1f} s;"
                  f" record in {out}")


def main() -> None:
    app()


if __name__ == "__main__":
    main()
