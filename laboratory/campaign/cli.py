"""`station campaign SPEC.toml`: a Monte Carlo campaign of laboratory runs (docs/campaigns.md)."""


import math
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated

import typer

from laboratory.app import command, fail, one_line, real_console, refused


def add_commands(app: typer.Typer) -> None:
    """Register `station campaign` on ``app``."""

    @command(app, "campaign")
    def campaign(
        spec_file: Annotated[Path, typer.Argument(help="the campaign spec (TOML: command, "
                             "seeds, seed, options, grid, random)")],
        out: Annotated[Path | None, typer.Option("--out", help="campaign directory "
                       "(default runs/campaign/<UTC time>)")] = None,
        scheduler: Annotated[str | None, typer.Option("--scheduler", help="address of an "
                             "existing Dask scheduler (default: an embedded LocalCluster)")
                             ] = None,
        workers: Annotated[int | None, typer.Option("--workers", help="LocalCluster worker "
                           "processes (default one per core; 0: in this process, no Dask)")
                           ] = None,
        resume: Annotated[bool, typer.Option("--resume", help="continue the campaign in "
                          "--out: run only the tasks it has not stored")] = False,
        retries: Annotated[int, typer.Option("--retries", help="more attempts of a task "
                           "that raised outside the laboratory")] = 2,
        quiet: Annotated[bool, typer.Option("--quiet", help="no progress bar")] = False,
    ) -> None:
        """Run many laboratory runs over seeds and sweeps on Dask; Parquet rows and a
        summary (observed rms error / predicted sigma per constant) under --out."""
        from laboratory.campaign.run import run_campaign
        from laboratory.campaign.spec import SpecError, load_spec

        if workers is not None and workers < 0:
            fail(f"--workers must be 0 or more, got {workers}")
        if scheduler is not None and workers is not None:
            fail("--workers sizes the embedded cluster; not with --scheduler")
        if retries < 0:
            fail(f"--retries must be 0 or more, got {retries}")
        if resume and out is None:
            fail("--resume needs --out (the campaign to continue)")
        try:
            spec = load_spec(spec_file)
        except SpecError as e:
            refused(e)
        if out is None:
            out = Path("runs/campaign") / datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
        try:
            res = run_campaign(spec, out, scheduler=scheduler, workers=workers,
                               resume=resume, retries=retries, console=real_console(),
                               quiet=quiet)
        except (SpecError, OSError) as e:
            refused(e)
        show(res.summary)
        from laboratory.campaign.store import CampaignStore

        failures = CampaignStore(res.out).table("failures")
        for f in failures.itertuples():
            typer.echo(f"task {f.task} (seed {f.seed}) failed: {f.message}")
        typer.echo(f"{res.n_tasks} tasks: {res.ran} run now, {res.stored_before} stored "
                   f"before, {len(failures)} failed; Parquet and summary in {res.out}")


def _g(x: object) -> str:
    return "" if not isinstance(x, float) or math.isnan(x) else f"{x:.4g}"


def show(summary: object) -> None:
    """The summary on screen: the constants with a predicted sigma."""
    import pandas as pd

    assert isinstance(summary, pd.DataFrame)
    rows = summary[summary["ratio"].notna()] if not summary.empty else summary
    if rows.empty:
        return
    from rich.table import Table

    from laboratory.campaign.summary import ESTIMATORS

    per = [e for e in ESTIMATORS if f"ratio_{e}" in rows.columns]
    lead = [c for c in rows.columns if c not in (
        "instrument", "parameter", "units", "n", "rms_error", "rms_sigma", "ratio", "low",
        "high", "inside", "max_abs_z") and not c.endswith(tuple(f"_{e}" for e in per))]
    t = Table(title="observed rms error / predicted sigma (99 % chi-square interval)")
    for c in [*lead, "constant", "n", "rms error", "rms sigma", "ratio", "interval",
              "max |z|", *(f"ratio {e.replace('_', '-')}" for e in per)]:
        t.add_column(c)
    for r in rows.to_dict("records"):
        mark = "" if r["inside"] else " [red]outside[/red]"
        t.add_row(*[one_line(r[c]) for c in lead], f"{r['instrument']} {r['parameter']}",
                  str(r["n"]), _g(r["rms_error"]), _g(r["rms_sigma"]),
                  _g(r["ratio"]) + mark, f"{_g(r['low'])}..{_g(r['high'])}",
                  _g(r["max_abs_z"]), *(_g(r[f"ratio_{e}"]) + (
                      "" if r[f"inside_{e}"] in (True, None) else " [red]outside[/red]")
                      for e in per))
    real_console().print(t)
