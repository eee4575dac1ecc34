"""The CIGTF laboratory's command: `station gyrocompass-test`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from laboratory.app import (
    OutOpt,
    ResumeOpt,
    check_seed,
    command,
    console,
    finished,
    new_or_resumed,
    reported,
    station_run,
)
from laboratory.identity import OperatorOpt, invoked


def add_commands(app: typer.Typer) -> None:
    """Register this laboratory's commands on the station's command line."""

    @command(app, "gyrocompass-test")
    def gyrocompass_test(
        seed: Annotated[int | None, typer.Option("--seed", help="run seed (default 1; when "
                        "resuming, the run's)")] = None,
        out: OutOpt = None,
        resume: ResumeOpt = None,
        analyse: Annotated[Path | None, typer.Option(
            "--analyse", help="recompute the phase analysis from the journal in this "
            "directory (e.g. after a stop), with the run's own config.toml unless "
            "--config")] = None,
        config: Annotated[Path | None, typer.Option("--config", help="TOML with a \\[cigtf] "
                          "section (latitude_deg, noise and misalignment magnitudes)")] = None,
        eq27: Annotated[bool, typer.Option(
            "--eq27", help="correct each phase's theta by eq. 27 (report 001, Appendix II) "
            "with the \\[cigtf.eq27] values: levels' b, c, gyro's D_I, D_OS, the 180 deg "
            "null's error")] = False,
        links: Annotated[Path | None, typer.Option("--links", help="run against the rack "
                         "`station serve --station cigtf --links DIR` serves (real time)")] = None,
        operator: OperatorOpt = None,
    ) -> None:
        """The CIGTF gyrocompassing accuracy test (report 001) on the simulated fixture."""
        from laboratory.cigtf.gyrocompassing import (
            analyse_journal,
            render_tables,
            run_gyrocompass_test,
        )
        from station.config.cigtf import load_cigtf_eq27, load_cigtf_limits, load_cigtf_params

        check_seed(seed)
        if analyse is not None:
            from laboratory.cigtf.gyrocompassing import run_config

            with reported(lambda: None):
                cfg = run_config(analyse, config)
                e27 = load_cigtf_eq27(config)
                res = analyse_journal(analyse, load_cigtf_params(cfg), load_cigtf_limits(cfg),
                                      e27.model_copy(update={"apply": True})
                                      if eq27 or e27.apply else None)
            for p in res["phases"]:
                typer.echo(f"{p['phase']:>9}: theta {p['theta_arcsec']:+.2f} +/- "
                           f"{p['sigma_arcsec']:.2f} arcsec (n = {p['n']}, from the journal)")
            for p in (res["eq27"] or {}).get("phases", []):
                typer.echo(f"{p['phase']:>9}: theta (eq. 27) {p['theta_arcsec']:+.2f} +/- "
                           f"{p['sigma_arcsec']:.2f} arcsec")
            for m in res["incomplete_phases"]:
                typer.echo(f"{m} (from the journal)")
            typer.echo(f"{len(res['runs'])} completed runs; written "
                       f"{analyse / 'gyrocompass_analysis.json'}")
            return
        target, args = new_or_resumed("gyrocompass-test", out, resume, {"seed": seed})
        run_seed = 1 if args["seed"] is None else args["seed"]
        from station.config.identity import load_identity

        with reported(lambda: None):
            limits = load_cigtf_limits(config)
            e27 = load_cigtf_eq27(config)
            e27 = e27.model_copy(update={"apply": e27.apply or eq27})
            unit = load_identity(config, "CIGTF")
        with invoked(operator, identity=unit):
            res, target = station_run(
                load_cigtf_params, config, "gyrocompass", run_seed, target, resume is not None,
                lambda params, d: run_gyrocompass_test(run_seed, d, params=params, links=links,
                                                       resume=resume is not None, limits=limits,
                                                       eq27=e27))
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
        finished(res, target, ".1f")
