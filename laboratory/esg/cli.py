"""The ESG laboratory's command: `station esg-calibration`."""

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

    @command(app, "esg-calibration")
    def esg_calibration(
        seed: Annotated[int | None, typer.Option("--seed", help="run seed (default 1; when "
                        "resuming, the run's)")] = None,
        out: OutOpt = None,
        resume: ResumeOpt = None,
        config: Annotated[Path | None, typer.Option("--config", help="TOML with an \\[esg] "
                          "section (site, rotor, \\[esg.pattern], \\[esg.signal])")] = None,
        links: Annotated[Path | None, typer.Option("--links", help="run against the rack "
                         "`station serve --station esg --links DIR` serves (real time)")] = None,
        operator: OperatorOpt = None,
    ) -> None:
        """The strapdown ESG pattern calibration and readout study (report 004)."""
        from laboratory.esg.calibration import render_tables, run_esg_calibration
        from station.config.esg import load_esg_limits, load_esg_params

        check_seed(seed)
        target, args = new_or_resumed("esg-calibration", out, resume, {"seed": seed})
        run_seed = 1 if args["seed"] is None else args["seed"]
        from station.config.identity import load_identity

        with reported(lambda: None):
            limits = load_esg_limits(config)
            unit = load_identity(config, "ESG")
        with invoked(operator, identity=unit):
            res, target = station_run(
                load_esg_params, config, "esg", run_seed, target, resume is not None,
                lambda params, d: run_esg_calibration(run_seed, d, params=params, links=links,
                                                      resume=resume is not None, limits=limits))
        render_tables(console, res)
        if "served" in res:
            console.print(f"served rack (session {res['served']['session']}): "
                          f"{res['served']['note']} (pickoff-1 coning only: the true colatitudes "
                          "depend on the served rack's path and are left out)", markup=False)
        finished(res, target, ".1f")
