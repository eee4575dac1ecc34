"""Command line: `station check`, the procedure commands, serving and comparing.

Every everyday mistake (an unknown chart, a bad number, a missing or unwritable path, a
directory that already holds a record) ends with one line on stderr and exit 2, before
anything is written; a procedure that stops says so on stderr, naming the step, with exit 1.
Both are operator errors (station/errors.py) and end a command in one place, ``end``.
"""


import json
import sys
from pathlib import Path
from typing import Annotated

import typer

from laboratory.app import (
    ConfigOpt,
    SeedOpt,
    StationOpt,
    app,
    command,
    end,
    fail,
    lab_config,
    one_line,
    real_console,
    refused,
)
from station.errors import OperatorError, StopError


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


@command(app)
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

    lab, cfg = lab_config(station, config, None)
    try:
        results = check_all(lab, cfg, links, timeout)
    except (OperatorError, ValueError, OSError) as e:  # no or the wrong served rack
        refused(e)
    if as_json:
        typer.echo(json.dumps(as_dicts(results), indent=2))
    else:
        from rich.table import Table

        t = Table(title=f"Instrument check: {lab.title}")
        for col in ("instrument", "link", "ok", "identity / error"):
            t.add_column(col)
        for r in results:
            t.add_row(
                r.instrument, r.link, "[green]yes[/green]" if r.ok else "[red]NO[/red]", r.identity
            )
        real_console().print(t)
    bad = [r.instrument for r in results if not r.ok]
    if bad:
        typer.echo(f"not answering: {', '.join(bad)}", err=True)
        raise typer.Exit(1)


@command(app)
def labs() -> None:
    """List the laboratories the station knows (the --station names)."""
    from laboratory import registry

    for name in registry.names():
        try:
            typer.echo(f"{name}\t{registry.get(name).title}")
        except registry.UnknownLaboratory as e:
            typer.echo(f"{name}\t(cannot load: {one_line(e)})")


@command(app)
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
    lab, cfg = lab_config(station, config, seed)
    target = served_station(lab, cfg)
    names = [n for item in only or () for n in item.split(",") if n]
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    try:
        serve_rack(target, speed, links, names or None, can_port=can_port)
    except (OperatorError, ValueError, OSError) as e:
        refused(e)
    except RuntimeError as e:  # the simulation thread failed: serving stopped
        end(StopError(one_line(e)))


@command(app)
def compare(
    dir_a: Path,
    dir_b: Path,
    rel_tol: Annotated[float, typer.Option(help="ignore relative differences up to this")] = 0.0,
    rehearsal: Annotated[bool, typer.Option("--rehearsal", help="DIR_A is a run over links, "
                         "DIR_B its virtual twin: compare within the real-time tolerances "
                         "(docs/hil.md)")] = False,
) -> None:
    """Show which sheet and result values differ between two run directories."""
    from laboratory.compare import differences, render_differences

    if rehearsal:
        from station.hil.twin import compare_rehearsal

        problems = compare_rehearsal(dir_a, dir_b)  # a refusal: exit 2 (_command)
        console = real_console()
        for line in problems:
            console.print(line)
        console.print("equal within the real-time tolerances" if not problems
                      else f"{len(problems)} differences beyond the tolerances")
        raise typer.Exit(1 if problems else 0)
    if not rel_tol >= 0:
        fail(f"--rel-tol must be 0 or more, got {rel_tol:g}")
    diffs = differences(dir_a, dir_b, rel_tol)  # a refusal: exit 2 (_command)
    if not diffs:
        real_console().print("no differences")
        return
    render_differences(real_console(), diffs, dir_a, dir_b)
    raise typer.Exit(1)


@command(app)
def report(
    run_dir: Path,
    out: Annotated[Path | None, typer.Option("--out", help="the HTML file to write (default: "
                   "RUN_DIR/report.html)")] = None,
) -> None:
    """Write the run's report: one self-contained HTML file rendered from its record alone."""
    from laboratory.report import write_report

    typer.echo(f"report written: {write_report(run_dir, out)}")


regress_app = typer.Typer(no_args_is_help=True, rich_markup_mode=None,
                          help="Regression baselines: hold a new run against a stored "
                          "earlier run (docs/regression.md).")
app.add_typer(regress_app, name="regress")


@command(regress_app, "save")
def regress_save(run_dir: Path, baseline: Path) -> None:
    """Store RUN_DIR's constants (estimate, sigma) and sheets as the baseline file BASELINE."""
    from laboratory.regress import save

    rec = save(run_dir, baseline)
    typer.echo(f"baseline written: {baseline} ({len(rec['constants'])} constants, "
               f"{len(rec['sheets'])} sheets)")


@command(regress_app, "check")
def regress_check(
    run_dir: Path,
    baseline: Path,
    sigma: Annotated[float, typer.Option("--sigma", help="a regression: a constant moved "
                     "beyond this many combined sigma")] = 4.0,
    junit: Annotated[Path | None, typer.Option("--junit", help="also write the outcome as "
                     "JUnit XML to this file")] = None,
) -> None:
    """Hold RUN_DIR against BASELINE: constants in combined sigma, sheets exactly where the
    runs are replays; exit 1 on a regression."""
    from laboratory.regress import check as check_run
    from laboratory.regress import write_junit

    cases = check_run(run_dir, baseline, sigma)
    if junit is not None:
        write_junit(junit, cases)
    failed = [c for c in cases if c.failure is not None]
    for c in failed:
        real_console().print(c.failure, markup=False, highlight=False, soft_wrap=True)
    skipped = sum(c.skipped is not None for c in cases)
    typer.echo(f"{len(cases)} checked, {len(failed)} regressions, {skipped} skipped")
    if failed:
        raise typer.Exit(1)


def _usage_error() -> type[Exception]:
    """The parser's usage-error class (typer's own click, or click before typer 0.2x)."""
    import importlib

    for module in ("typer._click.exceptions", "click.exceptions"):
        try:
            return importlib.import_module(module).UsageError
        except (ImportError, AttributeError):
            continue
    raise ImportError("no click UsageError")


def _command_names() -> set[str]:
    """The commands and groups registered on the station's command line so far."""
    names = {g.name for g in app.registered_groups if g.name}
    for c in app.registered_commands:
        if c.name:
            names.add(c.name)
        elif c.callback is not None:  # typer's name for it: the function's, dashed
            names.add(c.callback.__name__.replace("_", "-"))
    return names


def _add_laboratory_commands(args: list[str]) -> None:
    """Each registered laboratory's own commands (its procedures' entry points); one that
    cannot be loaded is named on stderr and left out, the others still work. When the
    command line ``args`` names a command of the station or of a built-in laboratory, the
    installed packages are not scanned for more laboratories (issue 17: 5 ms of every
    run): a laboratory an installed package adds cannot take a built-in command's name."""
    from laboratory import registry

    try:
        names = registry.names(installed=False)
        _add_commands_of(names)
        if args and args[0] in _command_names():
            return
        more = [n for n in registry.names() if n not in names]
    except registry.UnknownLaboratory as e:
        typer.echo(f"warning: {one_line(e)}", err=True)
        return
    _add_commands_of(more)


def _add_commands_of(names: list[str]) -> None:
    from laboratory import registry

    for name in names:
        try:
            lab = registry.get(name)
        except registry.UnknownLaboratory as e:
            typer.echo(f"warning: {one_line(e)}", err=True)
            continue
        if lab.add_commands is not None:
            lab.add_commands(app)


_add_laboratory_commands(sys.argv[1:])


def _add_history_commands() -> None:
    """`station history` and `station trend`: the calibration history (laboratory/history)."""
    from laboratory.history.cli import add_commands

    add_commands(app)


_add_history_commands()


def _add_campaign_command() -> None:
    """`station campaign`: Monte Carlo campaigns on Dask (laboratory/campaign)."""
    from laboratory.campaign.cli import add_commands

    add_commands(app)


_add_campaign_command()


def main() -> None:
    """`station`: usage mistakes (an unknown option, a bad number) as one line on stderr."""
    usage_error = _usage_error()
    try:
        rc = app(standalone_mode=False)
    except usage_error as e:
        if type(e).__name__ == "NoArgsIsHelpError":  # a group without its command: the help
            typer.echo(e.format_message())  # type: ignore[attr-defined]
            sys.exit(2)
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


def start_plot_child(args: list[str]) -> None:
    """The plot child of the command ``args`` name (laboratory.app.PLOT_CHILDREN), started
    now: its imports then run beside the command's own (issue 17). None for a help. Such a
    command is a run: the garbage collector the script deferred waits for its imports
    (laboratory.startup: the run's connect turns it on again); any other, on again now."""
    from laboratory import startup
    from laboratory.app import PLOT_CHILDREN

    modules = PLOT_CHILDREN.get(args[0]) if args else None
    if modules and not {"--help", "-h"} & set(args):
        from laboratory import vcs
        from laboratory.plot_worker import start_early

        start_early(*modules)
        vcs.start()  # run.json's revision: git asked beside the imports
    else:  # not a run: the collector the script deferred is on again now
        startup.resume()


def run() -> None:
    """The `station` script: ``main``, then the process ends without the interpreter's
    teardown (laboratory.process_exit). ``main`` itself only raises SystemExit, for the
    callers that stay (tests)."""
    from laboratory.process_exit import finish

    start_plot_child(sys.argv[1:])
    try:
        main()
    except SystemExit as e:
        if e.code is None or isinstance(e.code, int):
            finish(e.code or 0)
        raise  # a message as the code: exit prints it
    finish(0)


if __name__ == "__main__":
    run()
