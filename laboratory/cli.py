"""Command line: `station check`, the procedure commands, serving and comparing.

Every everyday mistake (an unknown chart, a bad number, a missing or unwritable path, a
directory that already holds a record) ends with one line on stderr and exit 2, before
anything is written; a procedure that stops says so on stderr, naming the step, with exit 1.
Both are operator errors (station/errors.py) and end a command in one place, ``_exit``.
"""

from __future__ import annotations

import functools
import json
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any, NoReturn

import typer
from rich.console import Console
from rich.table import Table

from station.config.isu import ConfigError, load_config
from station.errors import BadArgument, OperatorError, StopError, UseError

app = typer.Typer(add_completion=False, no_args_is_help=True, help="The simulated ISU laboratory.")
console = Console() if Console().is_terminal else Console(width=110)

ConfigOpt = Annotated[
    Path | None, typer.Option("--config", help="station config TOML (merged over the default)")
]
SeedOpt = Annotated[int | None, typer.Option("--seed", help="run seed (default: the config's; "
                    "when resuming, the run's)")]
OutOpt = Annotated[Path | None, typer.Option("--out", help="new run directory (default: a "
                   "fresh runs/<command>/<UTC time>-seed<N>); never one that holds a record")]
ResumeOpt = Annotated[Path | None, typer.Option("--resume", help="continue the interrupted "
                      "run in this directory (its journal is appended to)")]
QuietOpt = Annotated[bool, typer.Option("--quiet", help="no live display")]


def version() -> str:
    """The installed package's version (the source tree's when not installed)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as dist_version

    try:
        return dist_version("isu-station")
    except PackageNotFoundError:
        from station import __version__

        return __version__


def _show_version(value: bool) -> None:
    if value:
        typer.echo(f"station {version()}")
        raise typer.Exit(0)


@app.callback()
def _root(
    show_version: Annotated[bool, typer.Option("--version", help="print the version and exit",
                            callback=_show_version, is_eager=True)] = False,
) -> None:
    """The simulated ISU laboratory: checks, procedures and rehearsals."""


def one_line(msg: object) -> str:
    """A message on one line (continuation lines joined with '; ')."""
    lines = [x.strip() for x in str(msg).splitlines() if x.strip()]
    return "; ".join(lines) if lines else type(msg).__name__


def _exit(e: OperatorError, run_dir: Path | None = None) -> NoReturn:
    """The one place an operator error ends a command: its line and its exit code.

    An error of use (exit 2): ``error: <line>`` on stderr. A stop (exit 1): ``stopped:
    <line>`` on stderr, with the journal that keeps every completed step when the run has a
    directory (``run_dir``). Exit 0 (a resumed run that was already complete): the line on
    stdout."""
    line = one_line(e)
    if e.exit_code == 0:
        typer.echo(line)
    elif isinstance(e, UseError):
        typer.echo(f"error: {line}", err=True)
    else:
        keep = (f" (the journal keeps every completed step: {run_dir / 'journal.jsonl'}; "
                f"continue with --resume {run_dir})") if run_dir is not None else ""
        typer.echo(f"stopped: {line}{keep}", err=True)
    raise typer.Exit(e.exit_code) from None


def _refused(e: Exception, run_dir: Path | None = None) -> NoReturn:
    """``_exit`` for an operator error; a builtin refusal (ValueError, OSError) met at a
    command's boundary is an error of use with the same line."""
    _exit(e if isinstance(e, OperatorError) else UseError(one_line(e)), run_dir)


def fail(msg: object) -> NoReturn:
    """A refused argument: one line on stderr, exit 2 (the command was not run as asked)."""
    _exit(BadArgument(one_line(msg)))


def _load(config: Path | None, seed: int | None = None):
    _check_seed(seed)
    try:
        return load_config(config, seed=seed)
    except ConfigError as e:  # the option too, so the user knows which argument to mend
        _exit(e if config is None else ConfigError(f"--config: {e}"))
    except (OSError, ValueError, RecursionError) as e:  # defence: the loader's ConfigError
        _exit(ConfigError(f"--config {config}: "
                          f"{getattr(e, 'strerror', None) or one_line(e)}"))


def _check_seed(seed: int | None) -> None:
    if seed is not None and seed < 0:
        fail(f"--seed must be 0 or more, got {seed}")


@contextmanager
def _reported(where: Callable[[], Path | None]) -> Iterator[None]:
    """Any operator error (or builtin refusal) of the block ends the command through
    ``_exit``; a stop names the journal in the run directory ``where()``."""
    try:
        yield
    except BrokenPipeError:  # the reader of stdout went away: the parser's own handling
        raise
    except (OperatorError, ValueError, OSError) as e:
        _refused(e, where())


def _command(*args: Any, **kwargs: Any) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """``app.command`` whose whole body reports operator errors (``_reported``): every
    command ends on one through the same ``_exit``."""
    def register(fn: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(fn)
        def run(*a: Any, **k: Any) -> Any:
            with _reported(lambda: None):
                return fn(*a, **k)

        return app.command(*args, **kwargs)(run)

    return register


def _new_or_resumed(command: str, out: Path | None, resume: Path | None,
                    given: dict[str, Any]) -> tuple[Path | None, dict[str, Any]]:
    """The run directory (None: a fresh one, claimed once the seed is known) and the run's
    arguments: when resuming, those the journal's start note recorded, where not given."""
    from laboratory.rundir import RunComplete, inspect_resume, resumed_args

    if out is not None and resume is not None:
        fail("give --out DIR for a new run or --resume DIR to continue one, not both")
    if resume is None:
        return out, given
    with _reported(lambda: None):
        s = inspect_resume(resume)
        args = resumed_args(s, given, command)
        if s.complete:
            raise RunComplete(f"{resume}: that run is complete (its journal holds the end "
                              "note): nothing to resume")
        return resume, args


def _target(out: Path | None, command: str, seed: int) -> Path:
    """``out``, or a fresh run directory under runs/<command> for this seed."""
    if out is not None:
        return out
    from laboratory.rundir import fresh

    with _reported(lambda: None):
        return fresh(Path("runs") / command, seed)


def _release(d: Path, fresh_dir: bool) -> None:
    """Remove a fresh run directory a refused run left empty."""
    if fresh_dir:
        try:
            d.rmdir()
        except OSError:
            pass


StationOpt = Annotated[str, typer.Option("--station", help="which laboratory: isu (default), "
                      "cigtf or esg (station labs lists them)")]


def _lab_config(station: str, config: Path | None, seed: int | None) -> tuple[Any, Any]:
    """The laboratory of ``--station`` and its config read as its own commands read it."""
    from laboratory import registry

    _check_seed(seed)
    try:
        lab = registry.get(station)
    except registry.UnknownLaboratory as e:
        _refused(e)
    if station == "isu":
        return lab, _load(config, seed)
    try:
        return lab, lab.load_config(config, seed)
    except ConfigError as e:  # the option too, so the user knows which argument to mend
        _exit(e if config is None else ConfigError(f"--config: {e}"))


@_command()
def check(
    config: ConfigOpt = None,
    as_json: Annotated[bool, typer.Option("--json", help="print the results as JSON")] = False,
    timeout: Annotated[float, typer.Option(help="reply timeout per instrument, s")] = 2.0,
    links: Annotated[Path | None, typer.Option("--links", help="check the rack served under "
                     "this directory instead")] = None,
    station: StationOpt = "isu",
) -> None:
    """Talk to every instrument over its link; exit 1 naming any that does not answer."""
    from laboratory.check import as_dicts, check_all

    lab, cfg = _lab_config(station, config, None)
    try:
        results = check_all(lab, cfg, links, timeout)
    except (OperatorError, ValueError, OSError) as e:  # no or the wrong served rack
        _refused(e)
    if as_json:
        typer.echo(json.dumps(as_dicts(results), indent=2))
    else:
        t = Table(title=f"Instrument check: {lab.title}")
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


@_command()
def labs() -> None:
    """List the laboratories the station knows (the --station names)."""
    from laboratory import registry

    for name in registry.names():
        try:
            typer.echo(f"{name}\t{registry.get(name).title}")
        except registry.UnknownLaboratory as e:
            typer.echo(f"{name}\t(cannot load: {one_line(e)})")


LinksOpt = Annotated[Path | None, typer.Option(
    "--links", help="run over the links of a rack served under this directory "
    "(station serve --links DIR), in real time")]


@_command()
def day(
    config: ConfigOpt = None,
    seed: SeedOpt = None,
    out: OutOpt = None,
    only: Annotated[list[str] | None, typer.Option("--only", help="measure only these charts "
                    "(II-6, II-7, II-7Q, II-10, II-11..II-14); repeatable")] = None,
    positions: Annotated[list[int] | None, typer.Option("--positions", help="only these "
                         "calibration positions (1-15; a pair m, m+1 is measured whole); "
                         "repeatable")] = None,
    resume: ResumeOpt = None,
    links: LinksOpt = None,
    start_at: Annotated[float, typer.Option("--start-at", help="virtual run: begin at this "
                        "simulated time, s (to compare with a rehearsal that began then)")
                        ] = 0.0,
    quiet: QuietOpt = False,
) -> None:
    """The full calibration day: turn-on, survey, positions 1-15, computations, alignments.

    Virtual time by default; with --links, in real time against a served rack (or hardware).
    """
    from laboratory.isu.day import DayRequest, check_selection, run_day

    _check_seed(seed)
    if not (0.0 <= start_at < 1e7):
        fail(f"--start-at must be between 0 and 1e7 s, got {start_at:g}")
    target, args = _new_or_resumed("day", out, resume, {
        "seed": seed, "only": only or None, "positions": positions or None})
    sel_only = tuple(args["only"]) if args["only"] else None
    sel_pos = tuple(args["positions"]) if args["positions"] else None
    with _reported(lambda: None):
        check_selection(sel_only, sel_pos)
    cfg = _load(config, args["seed"])
    fresh_dir = target is None
    target = _target(target, "day", cfg.seed)
    try:
        with _reported(lambda: target):
            res = run_day(DayRequest(cfg, target, only=sel_only, positions=sel_pos,
                                     resume=resume is not None, links=links,
                                     start_s=start_at, quiet=quiet), console)
    except typer.Exit as e:
        _release(target, fresh_dir and e.exit_code == 2)
        raise
    typer.echo(f"{res['sim_seconds'] / 3600:.2f} h simulated in {res['wall_seconds']:.1f} s; "
               f"record in {target}")


@_command()
def align(
    method: Annotated[str | None, typer.Option("--method", help="mirror | level | "
                      "gyrocompass (required for a new run)")] = None,
    estimator: Annotated[str | None, typer.Option("--estimator", help="average | posterior | "
                         "hybrid (default average)")] = None,
    calibration: Annotated[Path | None, typer.Option("--calibration", help="run directory "
                           "whose Calibration Results Sheet to use (default: calibrate "
                           "first)")] = None,
    config: ConfigOpt = None,
    seed: SeedOpt = None,
    out: OutOpt = None,
    resume: ResumeOpt = None,
    links: LinksOpt = None,
    quiet: QuietOpt = False,
) -> None:
    """One alignment (Part III): mirror, level or gyrocompass, with the chosen estimator."""
    from laboratory.isu.align import AlignRequest, load_calibration, run_align

    _check_seed(seed)
    target, args = _new_or_resumed("align", out, resume, {
        "seed": seed, "method": method, "estimator_requested": estimator,
        "calibration": None if calibration is None else str(calibration)})
    method = args["method"]
    estimator = args["estimator_requested"] or "average"
    if method is None:
        fail("--method is required: mirror, level or gyrocompass")
    if method not in ("mirror", "level", "gyrocompass"):
        fail(f"--method: unknown method {method!r}: mirror, level or gyrocompass")
    if estimator not in ("average", "posterior", "hybrid"):
        fail(f"--estimator: unknown estimator {estimator!r}: average, posterior or hybrid")
    cal = None if args["calibration"] is None else Path(args["calibration"])
    if cal is not None:
        with _reported(lambda: None):
            load_calibration(cal)
    cfg = _load(config, args["seed"])
    fresh_dir = target is None
    target = _target(target, "align", cfg.seed)
    try:
        with _reported(lambda: target):
            res = run_align(AlignRequest(cfg, target, method, estimator, calibration=cal,
                                         links=links, resume=resume is not None,
                                         quiet=quiet), console)
    except typer.Exit as e:
        _release(target, fresh_dir and e.exit_code == 2)
        raise
    typer.echo(f"{res['sim_seconds'] / 3600:.2f} h simulated in {res['wall_seconds']:.1f} s; "
               f"record in {target}")


@_command()
def serve(
    config: ConfigOpt = None,
    seed: SeedOpt = None,
    speed: Annotated[float, typer.Option("--speed", help="simulated seconds per wall "
                     "second")] = 1.0,
    links: Annotated[Path, typer.Option("--links", help="directory for the pty symlinks "
                     "and links.json")] = Path("runs/links"),
    only: Annotated[list[str] | None, typer.Option("--only", help="serve only these "
                    "instruments (repeatable, or comma-separated)")] = None,
    can_port: Annotated[int, typer.Option("--can-port", help="socketcand TCP port (0: any "
                        "free port)")] = 0,
    station: Annotated[str, typer.Option("--station", help="which laboratory's rack: isu "
                       "(default; its config carries the seed), cigtf ([cigtf] config) or "
                       "esg ([esg] config; both seed 1 unless given)")] = "isu",
) -> None:
    """Serve a simulated rack in real time on ptys (the ISU's IEU also on socketcand and
    slcan), with a live status table; stop with Ctrl-C."""
    import logging

    from laboratory.connect import served_station
    from station.hil.server import serve as serve_rack

    if not speed > 0:
        fail(f"--speed must be > 0, got {speed:g}")
    lab, cfg = _lab_config(station, config, seed)
    target = served_station(lab, cfg)
    names = [n for item in only or () for n in item.split(",") if n]
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    try:
        serve_rack(target, speed, links, names or None, can_port=can_port)
    except (OperatorError, ValueError, OSError) as e:
        _refused(e)
    except RuntimeError as e:  # the simulation thread failed: serving stopped
        _exit(StopError(one_line(e)))


@_command()
def compare(
    dir_a: Path,
    dir_b: Path,
    rel_tol: Annotated[float, typer.Option(help="ignore relative differences up to this")] = 0.0,
    rehearsal: Annotated[bool, typer.Option("--rehearsal", help="DIR_A is a run over links, "
                         "DIR_B its virtual twin: compare within the real-time tolerances "
                         "(docs/hil.md)")] = False,
) -> None:
    """Show which sheet and result values differ between two run directories."""
    from laboratory.compare import differences

    if rehearsal:
        from station.hil.twin import compare_rehearsal

        problems = compare_rehearsal(dir_a, dir_b)  # a refusal: exit 2 (_command)
        for line in problems:
            console.print(line)
        console.print("equal within the real-time tolerances" if not problems
                      else f"{len(problems)} differences beyond the tolerances")
        raise typer.Exit(1 if problems else 0)
    if not rel_tol >= 0:
        fail(f"--rel-tol must be 0 or more, got {rel_tol:g}")
    diffs = differences(dir_a, dir_b, rel_tol)  # a refusal: exit 2 (_command)
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


def _station_run(load_params: Callable[[Path | None], Any], config: Path | None,
                 command: str, seed: int, out: Path | None, resume: bool,
                 run: Callable[[Any, Path], dict]) -> tuple[dict, Path]:
    """Load a station's params from ``config`` and ``run(params, dir)``: exit 2 on a bad
    config, directory or served rack, 1 when a step fails (the journal keeps every
    completed step). Returns the results and the run directory."""
    with _reported(lambda: None):
        try:
            params = load_params(config)
        except (OSError, ValueError, RecursionError) as e:  # defence: the loader's ConfigError
            if isinstance(e, ConfigError):
                raise
            raise ConfigError(f"--config {config}: "
                              f"{getattr(e, 'strerror', None) or one_line(e)}") from None
    fresh_dir = out is None
    target = _target(out, command, seed)
    try:
        with _reported(lambda: target):
            return run(params, target), target
    except typer.Exit as e:
        _release(target, fresh_dir and e.exit_code == 2)
        raise


@_command("gyrocompass-test")
def gyrocompass_test(
    seed: Annotated[int | None, typer.Option("--seed", help="run seed (default 1; when "
                    "resuming, the run's)")] = None,
    out: OutOpt = None,
    resume: ResumeOpt = None,
    analyse: Annotated[Path | None, typer.Option("--analyse", help="recompute the phase "
                       "analysis from the journal in this directory (e.g. after a stop)")] = None,
    config: Annotated[Path | None, typer.Option("--config", help="TOML with a [cigtf] "
                      "section (latitude_deg, noise and misalignment magnitudes)")] = None,
    links: Annotated[Path | None, typer.Option("--links", help="run against the rack "
                     "`station serve --station cigtf --links DIR` serves (real time)")] = None,
) -> None:
    """The CIGTF gyrocompassing accuracy test (report 001) on the simulated fixture."""
    from laboratory.cigtf.gyrocompassing import analyse_journal, render_tables, run_gyrocompass_test
    from station.config.cigtf import load_cigtf_params

    _check_seed(seed)
    if analyse is not None:
        with _reported(lambda: None):
            res = analyse_journal(analyse, load_cigtf_params(config))
        for p in res["phases"]:
            typer.echo(f"{p['phase']:>9}: theta {p['theta_arcsec']:+.2f} +/- "
                       f"{p['sigma_arcsec']:.2f} arcsec (n = {p['n']}, from the journal)")
        for m in res["incomplete_phases"]:
            typer.echo(f"{m} (from the journal)")
        typer.echo(f"{len(res['runs'])} completed runs; written "
                   f"{analyse / 'gyrocompass_analysis.json'}")
        return
    target, args = _new_or_resumed("gyrocompass-test", out, resume, {"seed": seed})
    run_seed = 1 if args["seed"] is None else args["seed"]
    res, target = _station_run(
        load_cigtf_params, config, "gyrocompass", run_seed, target, resume is not None,
        lambda params, d: run_gyrocompass_test(run_seed, d, params=params, links=links,
                                               resume=resume is not None))
    render_tables(console, res)
    for p in res["phases"]:
        console.print(f"{p['phase']:>9}: theta {p['theta_arcsec']:+.2f} +/- "
                      f"{p['sigma_arcsec']:.2f} arcsec (n = {p['n']})")
    truth = res["truth"]["theta_arcsec"]
    console.print(f"truth (eq. 26) {'absent' if truth is None else f'{truth:+.2f} arcsec'}; "
                  f"delta {res['delta_arcsec']:.2f}, Delta {res['Delta_arcsec']:.2f} arcsec")
    if "served" in res:
        console.print(f"served rack (session {res['served']['session']}): "
                      f"{res['served']['note']}", markup=False)
    typer.echo(f"{res['sim_seconds'] / 3600:.1f} h simulated in {res['wall_seconds']:.1f} s; "
               f"record in {target}")


@_command("esg-calibration")
def esg_calibration(
    seed: Annotated[int | None, typer.Option("--seed", help="run seed (default 1; when "
                    "resuming, the run's)")] = None,
    out: OutOpt = None,
    resume: ResumeOpt = None,
    config: Annotated[Path | None, typer.Option("--config", help="TOML with an [esg] "
                      "section (site, rotor, [esg.pattern], [esg.signal])")] = None,
    links: Annotated[Path | None, typer.Option("--links", help="run against the rack "
                     "`station serve --station esg --links DIR` serves (real time)")] = None,
) -> None:
    """The strapdown ESG pattern calibration and readout study (report 004)."""
    from laboratory.esg.calibration import render_tables, run_esg_calibration
    from station.config.esg import load_esg_params

    _check_seed(seed)
    target, args = _new_or_resumed("esg-calibration", out, resume, {"seed": seed})
    run_seed = 1 if args["seed"] is None else args["seed"]
    res, target = _station_run(
        load_esg_params, config, "esg", run_seed, target, resume is not None,
        lambda params, d: run_esg_calibration(run_seed, d, params=params, links=links,
                                              resume=resume is not None))
    render_tables(console, res)
    if "served" in res:
        console.print(f"served rack (session {res['served']['session']}): "
                      f"{res['served']['note']} (pickoff-1 coning only: the true colatitudes "
                      "depend on the served rack's path and are left out)", markup=False)
    typer.echo(f"{res['sim_seconds'] / 3600:.1f} h simulated in {res['wall_seconds']:.1f} s; "
               f"record in {target}")


def _usage_error() -> type[Exception]:
    """The parser's usage-error class (typer's own click, or click before typer 0.2x)."""
    import importlib

    for module in ("typer._click.exceptions", "click.exceptions"):
        try:
            return importlib.import_module(module).UsageError
        except (ImportError, AttributeError):
            continue
    raise ImportError("no click UsageError")


def _add_laboratory_commands() -> None:
    """Each registered laboratory's own commands (its procedures' entry points); one that
    cannot be loaded is named on stderr and left out, the others still work."""
    from laboratory import registry

    try:
        names = registry.names()
    except registry.UnknownLaboratory as e:
        typer.echo(f"warning: {one_line(e)}", err=True)
        return
    for name in names:
        try:
            lab = registry.get(name)
        except registry.UnknownLaboratory as e:
            typer.echo(f"warning: {one_line(e)}", err=True)
            continue
        if lab.add_commands is not None:
            lab.add_commands(app)


_add_laboratory_commands()


def main() -> None:
    """`station`: usage mistakes (an unknown option, a bad number) as one line on stderr."""
    usage_error = _usage_error()
    try:
        rc = app(standalone_mode=False)
    except usage_error as e:
        msg = one_line(e.format_message()) if e.format_message() else ""  # type: ignore[attr-defined]
        if msg:  # (empty: no arguments, the help was shown)
            ctx = getattr(e, "ctx", None)
            where = ctx.command_path if ctx is not None else "station"
            typer.echo(f"error: {where}: {msg}", err=True)
        sys.exit(2)
    except typer.Abort:
        typer.echo("aborted", err=True)
        sys.exit(130)
    sys.exit(rc if isinstance(rc, int) else 0)


if __name__ == "__main__":
    main()
