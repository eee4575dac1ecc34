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
console = Console()

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
) -> None:
    """Talk to every instrument over its configured link; exit 1 naming any that does not answer."""
    from station.check import as_dicts, check_all

    cfg = _load(config)
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


def main() -> None:
    app()
