"""The command line's common parts: the typer app, its shared options, and the one place
an operator error ends a command.

Every everyday mistake (an unknown chart, a bad number, a missing or unwritable path, a
directory that already holds a record) ends with one line on stderr and exit 2, before
anything is written; a procedure that stops says so on stderr, naming the step, with exit 1.
Both are operator errors (station/errors.py) and end a command in one place, ``end``. The
laboratories' commands (laboratory/<lab>/cli.py) are registered through ``command``.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, NoReturn

import typer

from station.errors import BadArgument, OperatorError, UseError, VerdictFailed

if TYPE_CHECKING:
    from rich.console import Console

    from station.config.isu import StationConfig

# rich_markup_mode None: click's plain help. Typer's rich help imports rich.markdown and
# markdown_it on every --help, 0.1 s of a 0.36 s start (issue 17); help texts hold no markup.
app = typer.Typer(add_completion=False, no_args_is_help=True, rich_markup_mode=None,
                  help="The simulated inertial-instrument laboratories.")


@functools.cache
def real_console() -> Console:
    """The commands' rich Console, made on first use: a command line that only parses or
    shows help never imports rich.console (issue 17). Piped: 110 columns unless COLUMNS
    says otherwise (rich reads COLUMNS itself). A broken pipe discards the output and the
    command goes on (laboratory.console)."""
    from laboratory.console import StationConsole

    return (StationConsole() if StationConsole().is_terminal
            or os.environ.get("COLUMNS", "").isdigit() else StationConsole(width=110))


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

LinksOpt = Annotated[Path | None, typer.Option(
    "--links", help="run over the links of a rack served under this directory "
    "(station serve --links DIR), in real time")]


def one_line(msg: object) -> str:
    """A message on one line (continuation lines joined with '; ')."""
    lines = [x.strip() for x in str(msg).splitlines() if x.strip()]
    return "; ".join(lines) if lines else type(msg).__name__


def end(e: OperatorError, run_dir: Path | None = None) -> NoReturn:
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
    elif isinstance(e, VerdictFailed):
        typer.echo(f"verdict: {line}", err=True)
    else:
        keep = (f" (the journal keeps every completed step: {run_dir / 'journal.jsonl'}; "
                f"continue with --resume {run_dir})") if run_dir is not None else ""
        typer.echo(f"stopped: {line}{keep}", err=True)
    raise typer.Exit(e.exit_code) from None


def finished(res: dict, target: Path, hours: str = ".2f") -> None:
    """A run command's last line (simulated hours, wall seconds, the record), then the exit
    its verdict asks for (``verdict_exit``)."""
    try:
        typer.echo(f"{res['sim_seconds'] / 3600:{hours}} h simulated in "
                   f"{res['wall_seconds']:.1f} s; record in {target}")
    except BrokenPipeError:  # the reader went away (a quiet run's first line): as the console
        real_console().on_broken_pipe()
    verdict_exit(res)


def verdict_exit(res: dict) -> None:
    """End a completed run whose verdict is FAIL with exit 3 and its line (the record and
    the report are complete by then); nothing otherwise."""
    v = res.get("verdict") or {}
    if v.get("outcome") == "FAIL":
        end(VerdictFailed(v["failed"]))


def refused(e: Exception, run_dir: Path | None = None) -> NoReturn:
    """``end`` for an operator error; a builtin refusal (ValueError, OSError) met at a
    command's boundary is an error of use with the same line."""
    end(e if isinstance(e, OperatorError) else UseError(one_line(e)), run_dir)


def fail(msg: object) -> NoReturn:
    """A refused argument: one line on stderr, exit 2 (the command was not run as asked)."""
    end(BadArgument(one_line(msg)))


def load_isu_config(config: Path | None, seed: int | None = None) -> StationConfig:
    """The ISU laboratory's config (``--config`` over the default, ``--seed``); a bad one
    ends the command (exit 2). Its reader (pydantic, the instruments' params) is imported
    here, not when the command line starts."""
    from station.config.isu import ConfigError, load_config

    check_seed(seed)
    try:
        return load_config(config, seed=seed)
    except ConfigError as e:  # the option too, so the user knows which argument to mend
        end(e if config is None else ConfigError(f"--config: {e}"))
    except (OSError, ValueError, RecursionError) as e:  # defence: the loader's ConfigError
        end(ConfigError(f"--config {config}: "
                          f"{getattr(e, 'strerror', None) or one_line(e)}"))


def check_seed(seed: int | None) -> None:
    if seed is not None and seed < 0:
        fail(f"--seed must be 0 or more, got {seed}")


@contextmanager
def reported(where: Callable[[], Path | None]) -> Iterator[None]:
    """Any operator error (or builtin refusal) of the block ends the command through
    ``end``; a stop names the journal in the run directory ``where()``."""
    try:
        yield
    except BrokenPipeError:  # the reader of stdout went away: the parser's own handling
        raise
    except (OperatorError, ValueError, OSError) as e:
        refused(e, where())


# command name -> the modules its plot child imports (laboratory.plot_worker): the station
# script starts that child as soon as the command line names the command (issue 17)
PLOT_CHILDREN: dict[str, tuple[str, ...]] = {}


def command(on: typer.Typer, *args: Any, plots: tuple[str, ...] = (), **kwargs: Any
            ) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """``on.command`` whose whole body reports operator errors (``reported``): every
    command, the laboratories' own too, ends on one through the same ``end``. ``plots``:
    the modules of the plot child the command draws its plots in (``PLOT_CHILDREN``)."""
    def register(fn: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(fn)
        def run(*a: Any, **k: Any) -> Any:
            with reported(lambda: None):
                return fn(*a, **k)

        if plots:
            PLOT_CHILDREN[args[0] if args else fn.__name__.replace("_", "-")] = plots
        return on.command(*args, **kwargs)(run)

    return register


def new_or_resumed(command: str, out: Path | None, resume: Path | None,
                    given: dict[str, Any]) -> tuple[Path | None, dict[str, Any]]:
    """The run directory (None: a fresh one, claimed once the seed is known) and the run's
    arguments: when resuming, those the journal's start note recorded, where not given."""
    from laboratory.rundir import RunComplete, inspect_resume, resumed_args

    if out is not None and resume is not None:
        fail("give --out DIR for a new run or --resume DIR to continue one, not both")
    if resume is None:
        return out, given
    with reported(lambda: None):
        s = inspect_resume(resume)
        args = resumed_args(s, given, command)
        if s.complete:
            raise RunComplete(f"{resume}: that run is complete (its journal holds the end "
                              "note): nothing to resume")
        return resume, args


def target_dir(out: Path | None, command: str, seed: int) -> Path:
    """``out``, or a fresh run directory under runs/<command> for this seed."""
    if out is not None:
        return out
    from laboratory.rundir import fresh

    with reported(lambda: None):
        return fresh(Path("runs") / command, seed)


def release(d: Path, fresh_dir: bool) -> None:
    """Remove a fresh run directory a refused run left empty."""
    if fresh_dir:
        try:
            d.rmdir()
        except OSError:
            pass


StationOpt = Annotated[str, typer.Option("--station", help="which laboratory: isu (default), "
                      "cigtf or esg (station labs lists them)")]


def lab_config(station: str, config: Path | None, seed: int | None) -> tuple[Any, Any]:
    """The laboratory of ``--station`` and its config read as its own commands read it."""
    from laboratory import registry
    from station.config.file import ConfigError

    check_seed(seed)
    try:
        lab = registry.get(station)
    except registry.UnknownLaboratory as e:
        refused(e)
    if station == "isu":
        return lab, load_isu_config(config, seed)
    try:
        return lab, lab.load_config(config, seed)
    except ConfigError as e:  # the option too, so the user knows which argument to mend
        end(e if config is None else ConfigError(f"--config: {e}"))


def station_run(load_params: Callable[[Path | None], Any], config: Path | None,
                 command: str, seed: int, out: Path | None, resume: bool,
                 run: Callable[[Any, Path], dict]) -> tuple[dict, Path]:
    """Load a station's params from ``config`` and ``run(params, dir)``: exit 2 on a bad
    config, directory or served rack, 1 when a step fails (the journal keeps every
    completed step). Returns the results and the run directory."""
    from station.config.file import ConfigError

    with reported(lambda: None):
        try:
            params = load_params(config)
        except (OSError, ValueError, RecursionError) as e:  # defence: the loader's ConfigError
            if isinstance(e, ConfigError):
                raise
            raise ConfigError(f"--config {config}: "
                              f"{getattr(e, 'strerror', None) or one_line(e)}") from None
    fresh_dir = out is None
    target = target_dir(out, command, seed)
    try:
        with reported(lambda: target):
            return run(params, target), target
    except typer.Exit as e:
        release(target, fresh_dir and e.exit_code == 2)
        raise
