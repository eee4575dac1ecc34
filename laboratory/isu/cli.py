"""The ISU calibration laboratory's commands: `station day` and `station align`."""


from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from laboratory.app import (
    ConfigOpt,
    LinksOpt,
    OutOpt,
    QuietOpt,
    ResumeOpt,
    SeedOpt,
    check_seed,
    command,
    fail,
    finished,
    load_isu_config,
    new_or_resumed,
    real_console,
    release,
    reported,
    target_dir,
)
from laboratory.identity import OperatorOpt, invoked
from laboratory.isu.plot_child import DAY_CHILD

if TYPE_CHECKING:
    from station.config.isu import StationConfig

TapeLibraryOpt = Annotated[Path | None, typer.Option("--tape-library", help="directory of "
                           "parameter tapes: take the one matching the experiment's Chart I-8 "
                           "parameters, or make one and file it there (default [alignment] "
                           "tape_library)")]


def _path(v: str | Path | None) -> Path | None:
    return None if v is None else Path(v)


def _instruments(option: str, text: str | None) -> list[int] | None:
    """``1,2`` -> [1, 2]; a one-line refusal naming the option otherwise."""
    if text is None:
        return None
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        fail(f"{option}: {text!r} is not a list of instrument numbers such as 1,2")


def required(cfg: "StationConfig", items: list[str] | None) -> "StationConfig":
    """The config with ``--require NAME=VALUE`` over its ``[plan]`` (ValueError naming an
    unknown name or a bad value)."""
    from station.config.plan import with_required

    return cfg.model_copy(update={"plan": with_required(cfg.plan, items or [])})


def without_bubble(cfg: "StationConfig", kinds: list[str] | None) -> "StationConfig":
    """The config with ``--no-bubble gyro|accel`` over its ``[calibration]`` (ValueError
    naming an unknown kind)."""
    from station.config.calibration import CalibrationOptions

    if not kinds:
        return cfg
    field = {"gyro": "bubble_gyro", "accel": "bubble_accel"}
    bad = [k for k in kinds if k not in field]
    if bad:
        raise ValueError(f"--no-bubble {bad[0]!r}: choose gyro or accel")
    opts = cfg.calibration or CalibrationOptions()
    return cfg.model_copy(update={"calibration": opts.model_copy(
        update={field[k]: False for k in kinds})})


def with_gyro_gate(cfg: "StationConfig", gate: str | None) -> "StationConfig":
    """The config with ``--gyro-gate clock|pulses`` over its ``[calibration]`` (ValueError
    naming an unknown gate)."""
    from station.config.calibration import CalibrationOptions

    if gate is None:
        return cfg
    if gate not in ("clock", "pulses"):
        raise ValueError(f"--gyro-gate {gate!r}: choose clock or pulses")
    from pydantic import ValidationError

    opts = cfg.calibration or CalibrationOptions()
    try:  # validated again: the config's other [calibration] choices may exclude it
        new = CalibrationOptions.model_validate({**opts.model_dump(), "gyro_gate": gate})
    except ValidationError as e:
        raise ValueError(f"--gyro-gate {gate}: {e.errors()[0]['msg']}") from None
    return cfg.model_copy(update={"calibration": new})


def add_commands(app: typer.Typer) -> None:
    """Register this laboratory's commands on the station's command line."""

    @command(app, plots=DAY_CHILD)
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
        prior: Annotated[Path | None, typer.Option("--prior", help="earlier run directory whose "
                         "Calibration Results Sheet gives every constant this run does not "
                         "measure (same unit, [identity] max_prior_age_days)")] = None,
        survey: Annotated[Path | None, typer.Option("--survey", help="earlier run directory "
                          "whose Survey Results Sheet is used instead of Chart I-2")] = None,
        tape_library: TapeLibraryOpt = None,
        require: Annotated[list[str] | None, typer.Option("--require", help="a required "
                           "accuracy over the config's [plan], NAME=VALUE (gyro_scale_factor, "
                           "gyro_drift_deg_hr, accel_scale_factor_ppm, accel_bias_micro_g, "
                           "max_gate_minutes); repeatable")] = None,
        no_bubble: Annotated[list[str] | None, typer.Option("--no-bubble", help="set these "
                             "positions 7-15 without bubble-level corrections, keeping the "
                             "survey's (II-6.1): gyro, accel; over the config's "
                             "[calibration]; repeatable")] = None,
        gyro_gate: Annotated[str | None, typer.Option("--gyro-gate", help="static gyro "
                             "positions 7-15: clock (counts over a clock preset) or pulses "
                             "(the time for a preset of pulses, II-5.2); over the config's "
                             "[calibration]")] = None,
        quiet: QuietOpt = False,
        operator: OperatorOpt = None,
    ) -> None:
        """The full calibration day: turn-on, survey, positions 1-15, computations, alignments.

        Virtual time by default; with --links, in real time against a served rack (or hardware).
        """
        from laboratory.isu.day import DayRequest, check_selection, run_day

        check_seed(seed)
        if not (0.0 <= start_at < 1e7):
            fail(f"--start-at must be between 0 and 1e7 s, got {start_at:g}")
        target, args = new_or_resumed("day", out, resume, {
            "seed": seed, "only": only or None, "positions": positions or None,
            "prior": None if prior is None else str(prior),
            "survey": None if survey is None else str(survey),
            "tape_library": None if tape_library is None else str(tape_library),
            "require": require or None, **({"no_bubble": no_bubble} if no_bubble else {}),
            **({"gyro_gate": gyro_gate} if gyro_gate else {})})
        sel_only = tuple(args["only"]) if args["only"] else None
        sel_pos = tuple(args["positions"]) if args["positions"] else None
        with reported(lambda: None):
            check_selection(sel_only, sel_pos)
        cfg = load_isu_config(config, args["seed"])
        with reported(lambda: None):
            cfg = required(cfg, args.get("require"))
            cfg = without_bubble(cfg, args.get("no_bubble"))
            cfg = with_gyro_gate(cfg, args.get("gyro_gate"))
        fresh_dir = target is None
        target = target_dir(target, "day", cfg.seed)
        try:
            with reported(lambda: target), invoked(operator):
                res = run_day(DayRequest(cfg, target, only=sel_only, positions=sel_pos,
                                         resume=resume is not None, links=links,
                                         start_s=start_at, quiet=quiet,
                                         prior=args.get("prior"), survey=args.get("survey"),
                                         tape_library=_path(args.get("tape_library"))),
                                 None if quiet else real_console())
        except typer.Exit as e:
            release(target, fresh_dir and e.exit_code == 2)
            raise
        finished(res, target)


    @command(app)
    def plan(
        config: ConfigOpt = None,
        out: Annotated[Path | None, typer.Option("--out", help="directory for the charts, "
                       "accuracy.csv and times.json (default runs/plan/<UTC>-seed<N>)")] = None,
        require: Annotated[list[str] | None, typer.Option("--require", help="a required "
                           "accuracy over the config's [plan], NAME=VALUE; repeatable")
                           ] = None,
        verify: Annotated[bool, typer.Option("--verify", help="measure the curves too: a "
                          "campaign of partial days per chart (II-18, II-19, II-24) beside "
                          "the prediction (verify.csv, verify_*.png)")] = False,
        seeds: Annotated[int, typer.Option("--seeds", help="--verify: days per collection "
                         "time")] = 100,
        times: Annotated[list[str] | None, typer.Option("--times", help="--verify: "
                         "CHART=T1,T2,... collection times of a chart (s; turns for II-18); "
                         "repeatable")] = None,
        scheduler: Annotated[str | None, typer.Option("--scheduler", help="--verify: an "
                             "existing Dask scheduler (default an embedded LocalCluster)")
                             ] = None,
        workers: Annotated[int | None, typer.Option("--workers", help="--verify: LocalCluster "
                           "workers (0: in this process)")] = None,
    ) -> None:
        """Accuracy against collection time (Charts II-18..II-24) for this station, predicted
        by the covariance model, and the collection times the requirements imply (II-6.2);
        with --verify, beside the rms errors a campaign of simulated days measures."""
        from laboratory.isu.planning import run_plan

        cfg = load_isu_config(config, None)
        with reported(lambda: None):
            cfg = required(cfg, require)
            if verify:
                from laboratory.isu.verify import check_options, parse_times

                check_options(seeds, workers, scheduler)
                study_times = parse_times(times)
            elif times or scheduler or workers is not None:
                raise ValueError("--times, --scheduler and --workers go with --verify")
        target = target_dir(out, "plan", cfg.seed)
        with reported(lambda: target):
            run_plan(cfg, target, real_console())
            if verify:
                from laboratory.isu.verify import run_verify

                run_verify(cfg, target, real_console(), seeds=seeds, seed=cfg.seed,
                           times=study_times, scheduler=scheduler, workers=workers,
                           config=config.resolve() if config else None, quiet=False)
        typer.echo(f"written {target}")


    @command(app)
    def align(
        method: Annotated[str | None, typer.Option("--method", help="mirror | level | "
                          "gyrocompass (required for a new run)")] = None,
        estimator: Annotated[str | None, typer.Option("--estimator", help="average | posterior | "
                             "hybrid (default average)")] = None,
        calibration: Annotated[Path | None, typer.Option("--calibration", help="run directory "
                               "whose Calibration Results Sheet to use (default: calibrate "
                               "first)")] = None,
        tape: Annotated[Path | None, typer.Option("--tape", help="parameter tape (Chart I-7) "
                        "for the posterior-mean technique, checked against this experiment's "
                        "Chart I-8 parameters")] = None,
        tape_library: TapeLibraryOpt = None,
        k: Annotated[int | None, typer.Option("--K", help="number of intervals K of the "
                     "level or gyrocompass record (default [alignment] level_K / gyro_K)")
                     ] = None,
        dt: Annotated[float | None, typer.Option("--dt", help="interval Delta t, s")] = None,
        ieu_period: Annotated[float | None, typer.Option("--ieu-period", help="IEU sample "
                              "period, s (divides Delta t)")] = None,
        eps_t: Annotated[float | None, typer.Option("--eps-t", help="Chart I-8: prediction "
                         "time after the data, s")] = None,
        sigma_g: Annotated[float | None, typer.Option("--sigma-g", help="Chart I-8: rms error "
                           "of g~, g")] = None,
        sigma_theta: Annotated[float | None, typer.Option("--sigma-theta", help="Chart I-8: rms "
                               "error of the prior vertical, arcsec")] = None,
        mirror_readings: Annotated[int | None, typer.Option("--mirror-readings", help="mirror "
                                   "alignment: autocollimator readings per mirror")] = None,
        alpha_readings: Annotated[int | None, typer.Option("--alpha-readings", help="level: "
                                  "readings of mirror 1's azimuth alpha1")] = None,
        theta1: Annotated[bool | None, typer.Option("--theta1/--no-theta1", help="level: use "
                          "the autocollimator's zenith angle theta1 (III-2.2)")] = None,
        surveyed_g: Annotated[bool | None, typer.Option("--surveyed-g/--no-surveyed-g",
                              help="use |g| from the survey (III-2.2, III-3.2)")] = None,
        surveyed_earth_rate: Annotated[bool | None, typer.Option(
            "--surveyed-earth-rate/--no-surveyed-earth-rate",
            help="gyrocompass: |omega^E| from the survey (III-3.2)")] = None,
        known_colatitude: Annotated[bool | None, typer.Option(
            "--known-colatitude/--no-known-colatitude",
            help="gyrocompass: the colatitude from the survey (III-3.2)")] = None,
        prior_attitude: Annotated[str | None, typer.Option("--prior-attitude", help="nominal "
                                  "T1 of Chart I-8 (I-3.1): resolvers, autocollimators or "
                                  "quick")] = None,
        quick_k: Annotated[int | None, typer.Option("--quick-K", help="intervals of the quick "
                           "alignment (--prior-attitude quick)")] = None,
        accels: Annotated[str | None, typer.Option("--accels", help="accelerometers used, e.g. "
                          "1,2 (two need --surveyed-g, III-2.2; the simple average only)")
                          ] = None,
        gyros: Annotated[str | None, typer.Option("--gyros", help="gyros used, e.g. 1 (a "
                         "reduced gyrocompass set needs every survey input, III-3.2)")] = None,
        config: ConfigOpt = None,
        seed: SeedOpt = None,
        out: OutOpt = None,
        resume: ResumeOpt = None,
        links: LinksOpt = None,
        quiet: QuietOpt = False,
        operator: OperatorOpt = None,
    ) -> None:
        """One alignment (Part III): mirror, level or gyrocompass, with the chosen estimator.

        Every choice of the alignment plan defaults to the config's [alignment] table.
        """
        from laboratory.isu.align import AlignRequest, command_plan, load_calibration, run_align
        from laboratory.isu.align import load_tape as read_tape_file
        from station.config.alignment import AlignPlan

        check_seed(seed)
        given_plan = {"K": k, "dt": dt, "ieu_period": ieu_period, "eps_t_s": eps_t,
                      "sigma_g_g": sigma_g, "sigma_theta_arcsec": sigma_theta,
                      "mirror_readings": mirror_readings, "alpha_readings": alpha_readings,
                      "mirror_zenith": theta1, "surveyed_g": surveyed_g,
                      "surveyed_earth_rate": surveyed_earth_rate,
                      "known_colatitude": known_colatitude, "prior_attitude": prior_attitude,
                      "quick_K": quick_k, "accels": _instruments("--accels", accels),
                      "gyros": _instruments("--gyros", gyros)}
        target, args = new_or_resumed("align", out, resume, {
            "seed": seed, "method": method, "estimator_requested": estimator,
            "calibration": None if calibration is None else str(calibration),
            "tape": None if tape is None else str(tape),
            "tape_library": None if tape_library is None else str(tape_library),
            "plan": {k: v for k, v in given_plan.items() if v is not None} or None})
        method = args["method"]
        estimator = args["estimator_requested"] or "average"
        if method is None:
            fail("--method is required: mirror, level or gyrocompass")
        if method not in ("mirror", "level", "gyrocompass"):
            fail(f"--method: unknown method {method!r}: mirror, level or gyrocompass")
        if estimator not in ("average", "posterior", "hybrid"):
            fail(f"--estimator: unknown estimator {estimator!r}: average, posterior or hybrid")
        cal = _path(args["calibration"])
        tape_file = _path(args.get("tape"))
        if tape_file is not None and estimator == "average":
            fail("--tape: the simple average uses no tape (give --estimator posterior or "
                 "hybrid)")
        with reported(lambda: None):
            if cal is not None:
                load_calibration(cal)
            if tape_file is not None:
                read_tape_file(tape_file)
        cfg = load_isu_config(config, args["seed"])
        with reported(lambda: None):
            recorded = args.get("plan") or {}
            plan = (AlignPlan.model_validate(recorded) if "level_K" in recorded  # resumed
                    else command_plan(cfg, method, recorded))
        fresh_dir = target is None
        target = target_dir(target, "align", cfg.seed)
        try:
            with reported(lambda: target), invoked(operator):
                req = AlignRequest(cfg, target, method, estimator, calibration=cal,
                                   tape=tape_file, tape_library=_path(args.get("tape_library")),
                                   plan=plan, links=links, resume=resume is not None,
                                   quiet=quiet)
                res = run_align(req, None if quiet else real_console())
        except typer.Exit as e:
            release(target, fresh_dir and e.exit_code == 2)
            raise
        finished(res, target)


    @command(app)
    def apply(
        cal_file: Annotated[Path, typer.Argument(help="calibration file (a day's "
                            "DIR/calibration.json)")],
        raw_file: Annotated[Path, typer.Argument(help="raw IEU samples (CSV with timer, "
                            "gyro1..3, A1S1..A3S2 columns, as DIR/alignments/*-ieu.csv)")],
        out: Annotated[Path | None, typer.Option("--out", help="compensated CSV to write "
                       "(default: RAW_FILE with -compensated.csv)")] = None,
    ) -> None:
        """Apply a calibration file to raw IEU pulse counts: angular increments (rad) and
        specific force (m/s^2) in the body frame, the Chart IV-1/IV-2 models inverted."""
        from laboratory.apply import apply_calibration, read_raw, write_compensated
        from laboratory.calfile import load as load_calfile

        cal = load_calfile(cal_file)
        raw = read_raw(raw_file)
        comp = apply_calibration(cal, raw)
        target = out or raw_file.with_name(raw_file.stem + "-compensated.csv")
        write_compensated(target, raw, comp)
        t = float(comp.dt.sum())
        w = comp.dtheta.sum(axis=0) / t * 180.0 / 3.141592653589793 * 3600.0
        f = (comp.force * comp.dt[:, None]).sum(axis=0) / t
        typer.echo(f"{comp.dt.size} samples, {t:.1f} s; mean rate "
                   f"{w[0]:.5f} {w[1]:.5f} {w[2]:.5f} deg/hr, mean specific force "
                   f"{f[0]:.6f} {f[1]:.6f} {f[2]:.6f} m/s^2 (B1 B2 B3); written {target}")
