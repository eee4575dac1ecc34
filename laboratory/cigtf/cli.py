"""The CIGTF laboratory's command: `station gyrocompass-test`."""


from pathlib import Path
from typing import Annotated

import typer

from laboratory.app import (
    OutOpt,
    ResumeOpt,
    check_seed,
    command,
    finished,
    new_or_resumed,
    real_console,
    reported,
    station_run,
)
from laboratory.cigtf.plot_child import PLOTS
from laboratory.identity import OperatorOpt, invoked


def add_commands(app: typer.Typer) -> None:
    """Register this laboratory's commands on the station's command line."""

    @command(app, "gyrocompass-test", plots=(PLOTS,))
    def gyrocompass_test(
        seed: Annotated[int | None, typer.Option("--seed", help="run seed (default 1; when "
                        "resuming, the run's)")] = None,
        out: OutOpt = None,
        resume: ResumeOpt = None,
        analyse: Annotated[Path | None, typer.Option(
            "--analyse", help="recompute the phase analysis from the journal in this "
            "directory (e.g. after a stop), with the run's own config.toml unless "
            "--config")] = None,
        config: Annotated[Path | None, typer.Option("--config", help="TOML with a [cigtf] "
                          "section (latitude_deg, noise and misalignment magnitudes)")] = None,
        eq27: Annotated[bool, typer.Option(
            "--eq27", help="correct each phase's theta by eq. 27 (report 001, Appendix II) "
            "with the [cigtf.eq27] values: levels' b, c, gyro's D_I, D_OS, the 180 deg "
            "null's error")] = False,
        vary: Annotated[str | None, typer.Option(
            "--vary", help="section 1's variation study: rotor-voltage=V1,V2,... or "
            "azimuth=DEG1,DEG2,... (orientation 1's vertical null); the test per setting "
            "into DIR/<name>-<value>, theta fitted against the variable "
            "(DIR/variation.json)")] = None,
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
        from laboratory.shown import Shown
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
        if vary is not None:
            if resume is not None or links is not None:
                with reported(lambda: None):
                    raise typer.BadParameter("--vary runs its own tests on the virtual "
                                             "rack: not with --resume or --links")
            _vary(vary, seed, out, config, eq27)
            return
        target, args = new_or_resumed("gyrocompass-test", out, resume, {"seed": seed})
        run_seed = 1 if args["seed"] is None else args["seed"]
        from station.config.identity import load_identity

        with reported(lambda: None):
            limits = load_cigtf_limits(config)
            e27 = load_cigtf_eq27(config)
            e27 = e27.model_copy(update={"apply": e27.apply or eq27})
            unit = load_identity(config, "CIGTF")
        console = real_console()

        def show(res: dict) -> None:
            """The results on the console, while the plot is drawn."""
            render_tables(console, res)
            for p in res["phases"]:
                console.print(f"{p['phase']:>9}: theta {p['theta_arcsec']:+.2f} +/- "
                              f"{p['sigma_arcsec']:.2f} arcsec (n = {p['n']})")
            truth = res["truth"]["theta_arcsec"]
            told = "absent" if truth is None else f"{truth:+.2f} arcsec"
            console.print(f"truth (eq. 26) {told}; delta {res['delta_arcsec']:.2f}, Delta "
                          f"{res['Delta_arcsec']:.2f} arcsec")
            if "served" in res:
                console.print(f"served rack (session {res['served']['session']}): "
                              f"{res['served']['note']}", markup=False)

        shown = Shown(show)
        with invoked(operator, identity=unit):
            res, target = station_run(
                load_cigtf_params, config, "gyrocompass", run_seed, target, resume is not None,
                lambda params, d: run_gyrocompass_test(run_seed, d, params=params, links=links,
                                                       resume=resume is not None, limits=limits,
                                                       eq27=e27, show=shown))
        shown.done(res)  # or its error, once the record is complete
        finished(res, target, ".1f")


def _vary(vary: str, seed: int | None, out: Path | None, config: Path | None,
          eq27: bool) -> None:
    """`--vary`: the variation study (laboratory/cigtf/variation.py) and its fit."""
    from laboratory.app import target_dir
    from laboratory.cigtf.variation import parse_vary, run_variation
    from station.config.cigtf import load_cigtf_eq27, load_cigtf_limits, load_cigtf_params

    run_seed = 1 if seed is None else seed
    with reported(lambda: None):
        try:
            name, values = parse_vary(vary)
        except ValueError as e:
            raise typer.BadParameter(str(e)) from None
        params = load_cigtf_params(config)
        limits = load_cigtf_limits(config)
        e27 = load_cigtf_eq27(config)
        e27 = e27.model_copy(update={"apply": e27.apply or eq27})
    target = target_dir(out, f"gyrocompass-vary-{name}", run_seed)
    with reported(lambda: target):
        res = run_variation(run_seed, target, name, values, params, limits, e27)
    console = real_console()
    for s in res["settings"]:
        console.print(f"{name} {s['value']:g}: theta {s['theta_arcsec']:+.2f} +/- "
                      f"{s['sigma_arcsec']:.2f} arcsec (both phases; truth "
                      f"{s['truth_arcsec']:+.2f})")
    console.print(f"sensitivity d theta / d {name}: {res['sensitivity']:+.4f} +/- "
                  f"{res['sigma']:.4f} {res['units']} (simulator "
                  f"{res['truth']['sensitivity']:+.4f}, {res['z']:+.2f} sigma)")
    if "error_sensitivity" in res:
        console.print(f"gyrocompassing error sensitivity (slope + 3600): "
                      f"{res['error_sensitivity']:+.4f} +/- {res['sigma']:.4f} "
                      f"(simulator {res['truth']['error_sensitivity']:+.4f})")
    console.print(f"written {target / 'variation.json'}")
