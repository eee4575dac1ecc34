"""`station history` and `station trend`: the calibration history's commands.

``station history index RUNS_DIR...`` indexes finished runs; ``station history UNIT`` lists
a unit's runs; ``station trend UNIT`` shows per constant the changes between consecutive
calibrations and the scatter across days, writes trend.png, and exits 1 when anything is
flagged (as ``station compare`` does on differences).
"""


import datetime as dt
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from laboratory.history.trend import Trend

DbOpt = Annotated[str | None, typer.Option(
    "--db", help="SQLAlchemy URL of the history database (default: $STATION_HISTORY_URL, "
    "else sqlite:///runs/history.sqlite); a plain path is an SQLite file")]


def _url(db: str | None) -> str | None:
    """``--db`` as a URL: a value without ``://`` is the path of an SQLite file."""
    if db is None:
        return None
    from laboratory.history.store import sqlite_url

    return db if "://" in db else sqlite_url(Path(db))


def _write_page(path: Path, ts: list["Trend"], unit: str, level: float, url: str | None,
                since: str | None) -> None:
    """`--html FILE`: the unit's history as the report's section, on a page of its own."""
    from sqlalchemy.engine import make_url

    from laboratory.app import fail
    from laboratory.history.section import shown
    from laboratory.history.store import default_url
    from laboratory.report import render_history_page
    from station.files import write_bytes

    n = len({p.run_uid for t in ts for p in t.points})
    page = render_history_page(shown(ts, unit, level, f"{n} calibrations of {unit}"),
                               make_url(url or default_url()).render_as_string(
                                   hide_password=True), since)
    try:
        write_bytes(path, page.encode("utf-8"))
    except OSError as e:
        fail(f"--html {path}: cannot write: {e.strerror or e}")
    typer.echo(f"trend page: {path}")


def add_commands(app: typer.Typer) -> None:
    """Register `history` and `trend` on the station's command line."""
    from laboratory.app import command, fail, real_console

    @command(app, "history")
    def history(
        args: Annotated[list[str], typer.Argument(
            help="UNIT (a serial: the ISU's or an instrument's), or: index RUNS_DIR...",
            metavar="UNIT | index RUNS_DIR...")],
        db: DbOpt = None,
    ) -> None:
        """List a unit's runs in the calibration history; `history index RUNS_DIR...`
        indexes every finished run under those directories."""
        from laboratory.history.store import index_dirs, runs_of, session

        if args[0] == "index":
            if len(args) < 2:
                fail("history index: give one or more run directories (RUNS_DIR...)")
            dirs = index_dirs([Path(a) for a in args[1:]], _url(db))
            typer.echo(f"indexed {len(dirs)} run(s)")
            return
        if len(args) > 1:
            fail(f"history: one UNIT, got {len(args)} arguments ({' '.join(args)})")
        unit = args[0]
        with session(_url(db)) as s:
            runs = runs_of(s, unit)
            cells = [[r.date, r.started_utc.strftime("%H:%M:%S"), r.laboratory,
                      r.command or "-", r.status, r.verdict or "-", str(r.seed or "-"),
                      str(sum(x.estimate is not None for x in r.results)), r.path]
                     for r in runs]
        if not cells:
            fail(f"history: no runs of unit {unit} in the history")
        from laboratory.tables import Column, print_fitted

        cols = [Column(c, right=c in ("seed", "constants"))
                for c in ("date", "UTC", "lab", "command", "status", "verdict", "seed",
                          "constants", "record")]
        print_fitted(real_console(), f"Runs of {unit}", cols, cells)

    @command(app, "trend")
    def trend(
        unit: Annotated[str, typer.Argument(help="the unit's serial")],
        since: Annotated[str | None, typer.Option(
            "--since", help="only calibrations from this UTC date on (YYYY-MM-DD)")] = None,
        level: Annotated[float, typer.Option(
            "--level", help="flag a change or a scatter beyond this two-sided level")] = 0.999,
        plot: Annotated[Path, typer.Option("--plot", help="the trend plot to write")]
        = Path("trend.png"),
        html: Annotated[Path | None, typer.Option(
            "--html", help="also write the report's History of this unit as this page")]
        = None,
        db: DbOpt = None,
    ) -> None:
        """Per constant of a unit: the change between consecutive calibrations (z from both
        sigmas), the scatter across days against the predicted sigma (chi-square), and
        trend.png; exit 1 when anything is flagged."""
        from laboratory.history.store import runs_of, session
        from laboratory.history.trend import COLUMNS, flags, trend_plot, trends, z_limit
        from laboratory.history.trend import cells as trend_cells

        day = None
        if since is not None:
            try:
                day = dt.date.fromisoformat(since)
            except ValueError:
                fail(f"--since {since}: not a date (YYYY-MM-DD)")
        zl = z_limit(level)  # ValueError: exit 2 naming --level
        with session(_url(db)) as s:
            ts = trends(runs_of(s, unit, day), level)
        if not ts:
            fail(f"trend: unit {unit} has no constant determined on two or more completed "
                 "runs in the history")
        from laboratory.tables import Column, print_fitted

        cols = [Column(c, right=c not in ("inst", "param", "units", "flag")) for c in COLUMNS]
        cells = []
        for t in ts:
            row = trend_cells(t)
            row[-1] = " ".join(f"[red]{f}[/]" for f in flags(t)) or "-"
            cells.append(row)
        print_fitted(real_console(), f"Trend of {unit}: changes between consecutive "
                     f"calibrations (flag |z| > {zl:.2f}, level {level:g})", cols, cells)
        trend_plot(ts, plot, unit, level)
        flagged = [(t, c) for t in ts for c in t.changes if c.flagged]
        for t, c in flagged:
            typer.echo(f"flagged: {t.name} changed by {c.delta:+.6g} {t.units or ''} "
                       f"(z {c.z:+.2f}) from {c.before.path} to {c.after.path}")
        for t in ts:
            if t.scatter_flagged:
                typer.echo(f"flagged: {t.name} scatters beyond its predicted sigma (chi2 "
                           f"{t.chi2:.2f} on {t.dof} dof, p {t.p_value:.3g})")
        typer.echo(f"trend plot: {plot}")
        if html is not None:
            _write_page(html, ts, unit, level, _url(db), since)
        if any(t.flagged for t in ts):
            raise typer.Exit(1)
