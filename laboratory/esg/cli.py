"""The ESG laboratory's command: `station esg-calibration`."""


from pathlib import Path
from typing import Annotated

import typer

from laboratory.app import (
    OutOpt,
    ResumeOpt,
    check_seed,
    command,
    fail,
    finished,
    new_or_resumed,
    real_console,
    reported,
    station_run,
)
from laboratory.esg.plot_child import PLOTS, STRATEGY, STUDY
from laboratory.identity import OperatorOpt, invoked

ORDER_CHOICES = ("5", "6", "7", "8", "9", "residuals")


def order_value(order: str | None) -> int | str | None:
    """--order as the reduction takes it: an int, "residuals", or None (not given)."""
    return int(order) if order is not None and order.isdigit() else order


def add_commands(app: typer.Typer) -> None:
    """Register this laboratory's commands on the station's command line."""

    @command(app, "esg-calibration", plots=(PLOTS, STUDY, STRATEGY))
    def esg_calibration(
        seed: Annotated[int | None, typer.Option("--seed", help="run seed (default 1; when "
                        "resuming, the run's)")] = None,
        out: OutOpt = None,
        resume: ResumeOpt = None,
        config: Annotated[Path | None, typer.Option("--config", help="TOML with an [esg] "
                          "section (site, rotor, [esg.pattern], [esg.signal])")] = None,
        links: Annotated[Path | None, typer.Option("--links", help="run against the rack "
                         "`station serve --station esg --links DIR` serves (real time)")] = None,
        order: Annotated[str | None, typer.Option("--order", help="eq. 11 polynomial order: "
                         "5..9 (the report's trials; default 7, or the config's "
                         "[esg.reduction] order) or 'residuals' (each schedule's choice by "
                         "the order trials)")] = None,
        extremity: Annotated[bool | None, typer.Option(
            "--extremity-setup/--preset-processor",
            help="set the lamps, discriminator and delay up at the pattern extremity after "
                 "spin-up (sheet ESG-DPX; default, or the config's [esg.procedure] "
                 "extremity_setup) or keep the processor's preset 20 us / 241 us")] = None,
        counters: Annotated[int | None, typer.Option(
            "--counters", help="the data processor's counters: 2 (the report's, pickoffs "
            "read two at a time; default, or the config's [esg.procedure] counters) or 3 "
            "(the three pickoffs read at once)")] = None,
        variants: Annotated[bool | None, typer.Option(
            "--strategy-variants/--no-strategy-variants",
            help="add the strategy study's variants (pattern types, sets of lines, "
                 "pickoff arrangements) and Figure 3 to the record (default off, or the "
                 "config's [esg.procedure] strategy_variants)")] = None,
        adjust: Annotated[bool | None, typer.Option(
            "--adjust-alignment/--check-alignment",
            help="shim the mount and translate pickoff 1 when their coning exceeds 3 / 15 "
                 "arcsec (default: check and stop; or the config's [esg.procedure] "
                 "adjust_alignment)")] = None,
        remount: Annotated[bool | None, typer.Option(
            "--remount-alignment/--no-remount-alignment",
            help="before step 1, remount the case with mirror 2 along the spindle and "
                 "align pickoff 2 by coning, then mount it back; after step 3 measure "
                 "pickoff 3's tilt towards mirror 1 and translate it out (implies "
                 "--adjust-alignment; default off, or the config's [esg.procedure] "
                 "remount_alignment)")] = None,
        mirror2: Annotated[bool | None, typer.Option(
            "--pickoff3-mirror2/--no-pickoff3-mirror2",
            help="with the remount, also measure pickoff 3's tilt towards mirror 2 in a "
                 "second remount after step 3 and translate both tilts out (about 3 h more; "
                 "implies --remount-alignment; default off, or the config's "
                 "[esg.procedure] pickoff3_mirror2)")] = None,
        operator: OperatorOpt = None,
    ) -> None:
        """The strapdown ESG pattern calibration and readout study (report 004)."""
        from laboratory.esg.calibration import render_tables, run_esg_calibration
        from laboratory.shown import Shown
        from station.config.esg import (
            load_esg_limits,
            load_esg_params,
            load_esg_procedure,
            load_esg_reduction,
        )

        check_seed(seed)
        if counters is not None and counters not in (2, 3):
            fail(f"--counters {counters}: give 2 or 3")
        if order is not None and order not in ORDER_CHOICES:
            fail(f"--order {order}: give one of {', '.join(ORDER_CHOICES)}")
        target, args = new_or_resumed("esg-calibration", out, resume,
                                      {"seed": seed, "order": order_value(order),
                                       "extremity_setup": extremity,
                                       "counters": counters,
                                       "strategy_variants": variants,
                                       "adjust_alignment": adjust,
                                       "remount_alignment": remount,
                                       "pickoff3_mirror2": mirror2})
        run_seed = 1 if args["seed"] is None else args["seed"]
        from station.config.identity import load_identity

        with reported(lambda: None):
            limits = load_esg_limits(config)
            unit = load_identity(config, "ESG")
            run_order = (args["order"] if args["order"] is not None
                         else load_esg_reduction(config).order)
            proc = load_esg_procedure(config)
        def chosen(option: str) -> bool:
            """The command line's choice of a procedure option, else the config's."""
            given = args.get(option)
            return bool(getattr(proc, option) if given is None else given)

        setup = chosen("extremity_setup")
        want_variants = chosen("strategy_variants")
        adjusting = chosen("adjust_alignment")
        remounting = chosen("remount_alignment")
        both3 = chosen("pickoff3_mirror2")
        from dataclasses import replace

        n_counters = args.get("counters")
        from procedures.esg.acquisition import EsgPlan

        # the site's latitude comes from the params (run_esg_calibration sets it)
        plan = EsgPlan(latitude_deg=0.0, extremity_setup=setup, adjust_alignment=adjusting,
                       alignment_iterations=proc.alignment_iterations,
                       remount_alignment=remounting, pickoff3_mirror2=both3)
        points = proc.strategy_variants_points if want_variants else None
        console = real_console()

        def show(res: dict) -> None:
            """The results on the console, while the last plot is drawn."""
            render_tables(console, res)
            if "served" in res:
                console.print(f"served rack (session {res['served']['session']}): "
                              f"{res['served']['note']} (pickoff-1 coning only: the true "
                              "colatitudes depend on the served rack's path and are left "
                              "out)", markup=False)

        shown = Shown(show)
        with invoked(operator, identity=unit):
            res, target = station_run(
                load_esg_params, config, "esg", run_seed, target, resume is not None,
                lambda params, d: run_esg_calibration(run_seed, d, params=params if n_counters
                                                      is None else replace(
                                                          params, counters=n_counters),
                                                      links=links,
                                                      resume=resume is not None, limits=limits,
                                                      order=run_order, plan=plan,
                                                      variants_points=points, show=shown))
        shown.done(res)  # or its error, once the record is complete
        finished(res, target, ".1f")
