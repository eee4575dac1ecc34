"""`station align`: the alignments of Part III on the simulated laboratory, and their record.

``run_align`` runs one alignment (method and estimation technique) after a calibration,
either the calibration of an earlier run directory (``calibration_dir``: its Calibration
Results and Survey Results sheets) or a full calibration day measured first in the same run,
and writes ``DIR/results.json`` with an ``alignment`` list, ``DIR/sheets/*.json``, the tapes
of the parameter evaluation in ``DIR/tapes`` and the journal.

``day_alignments`` is what ``station day`` calls after its calibration: all three methods,
level and gyrocompass alignment each processed by both techniques. ``AlignRequest`` says what
one `station align` run does, where and how; the procedures get one ``AlignmentOptions``.

Errors are taken against the simulator's true attitude at the time each alignment refers to
(``Outcome.t_ref``): the small rotation between the estimated and the true T in earth axes,
about east and north (level errors) and about up (azimuth error). Only this module and
``laboratory.isu.truth`` look at the simulator; the predicted sigmas come from the procedures.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from pydantic import BaseModel, ValidationError

from laboratory import registry
from laboratory.calfile import write_day_calibration
from laboratory.connect import connect
from laboratory.export import can_log, write_alignment_samples, write_results_csv
from laboratory.history import index_after
from laboratory.identity import identified, isu_config, isu_identity
from laboratory.isu.display import DayDisplay, shown_console
from laboratory.isu.spec import noise_spec, site_of
from laboratory.record import write_results, write_sheets
from laboratory.report import report_after
from laboratory.rundir import opened_journal, prepare, resume_note
from laboratory.tables import Column, print_fitted
from laboratory.verdicts import judge_alignments, run_verdict
from procedures.isu.alignment import estimation as es
from procedures.isu.alignment.align_math import ARCSEC, rotation_error_arcsec
from procedures.isu.alignment.common import Outcome, canonical_estimator
from procedures.isu.alignment.options import DAY_ESTIMATORS, AlignmentOptions
from procedures.isu.alignment.parameter_sheet import Tape
from procedures.isu.alignment.preprocess import Constants, MissingConstants
from procedures.isu.alignment.results_sheet import AlignPlan
from procedures.isu.alignment.run import run_alignments
from procedures.isu.alignment.tape_library import TapeLibrary
from procedures.isu.computations import compute_calibration
from procedures.isu.day import measure_day
from procedures.isu.plan import DayPlan
from procedures.isu.sheets import ISU_SHEETS, CalibrationResults, SurveyResults, sheets_used
from procedures.isu.turn_on import turn_on
from procedures.runner import Run
from station.config.isu import StationConfig
from station.racks.isu import SimulatedRack

if TYPE_CHECKING:
    from rich.console import Console

    from sim.isu.world import World
    from station.drivers.isu import IsuDrivers

T = TypeVar("T", bound=BaseModel)
# The largest azimuth sigma (1 sigma, from the gyros' noise alone) at which a gyrocompass
# alignment is still reported: beyond it the mirror alignment is the laboratory's way.
AZIMUTH_SIGMA_LIMIT_DEG = 1.0


def alignment_entries(outcomes: list[Outcome], world: World | None) -> list[dict]:
    """results.json entries: estimate against the true attitude at each ``t_ref``
    (``world`` None, over links: the attitude is the server's, errors are absent)."""
    out = []
    for o in outcomes:
        sig = o.predicted_sigma_arcsec
        t_true: list | None = None
        level: list[float | None] = [None, None]
        az: float | None = None
        z: list[float | None] = [None, None, None]
        if world is not None:
            t_be = world.attitude(o.t_ref).T  # world.attitude is T^BE; T = T^EB
            err = rotation_error_arcsec(o.t, t_be)
            e, n, az = err["east"], err["north"], err["azimuth"]
            level, z = [e, n], [e / sig[0], n / sig[1], az / sig[2]]
            t_true = t_be.tolist()
        out.append({
            "method": o.method,
            "estimator": o.estimator,
            "K": int(o.K),
            "dt": float(o.dt),
            "level_error_arcsec": level,
            "azimuth_error_arcsec": az,
            "predicted_sigma_arcsec": list(sig),
            "physical_limit_arcsec": list(o.physical_limit_arcsec),
            "error_over_sigma": z,
            "t_ref_s": o.t_ref,
            "T": o.t.tolist(),
            "T_true": t_true,
        })
    return out


def day_methods(calib: CalibrationResults) -> dict[str, tuple[str, ...]]:
    """The day's alignments that ``calib`` allows: mirror always, level with every
    accelerometer constant, gyrocompass with every gyro constant too (a partial day,
    ``station day --only``, leaves some out instead of stopping)."""
    est = dict(DAY_ESTIMATORS)
    for method, gyros in (("level", False), ("gyrocompass", True)):
        try:
            Constants.from_sheet(calib, gyros)
        except MissingConstants:
            est.pop(method)
    return est


def gyrocompass_latitude_limit_deg(cfg: StationConfig, plan: AlignPlan | None = None) -> float:
    """The highest |latitude| at which the gyrocompass alignment gives an azimuth.

    Its azimuth comes from the horizontal Earth rate Omega cos(latitude) against the gyros'
    rate noise over the record (angle random walk over K dt and the random drift; Chart
    III-11's limit, ``gyro_error_model``): sigma_az = noise / (Omega cos(latitude)). Where
    that floor alone passes AZIMUTH_SIGMA_LIMIT_DEG the small-angle error model behind
    the reported sigma no longer holds, and the result would be no alignment at all."""
    plan = plan or cfg.alignment.plan()
    noise = noise_spec(cfg)
    span_h = plan.gyro_K * plan.gyro_dt_s / 3600.0
    rate = math.sqrt(noise.gyro_arw_deg_rt_hr**2 / span_h + noise.gyro_drift_sigma_deg_hr**2)
    ratio = rate / (cfg.site.earth_rate_deg_per_hr * math.radians(AZIMUTH_SIGMA_LIMIT_DEG))
    return math.degrees(math.acos(min(1.0, ratio)))


def gyrocompass_refusal(cfg: StationConfig, plan: AlignPlan | None = None) -> str | None:
    """Why the gyrocompass alignment is meaningless at the site's latitude (None: it is not)."""
    lim = gyrocompass_latitude_limit_deg(cfg, plan)
    lat = cfg.site.latitude_deg
    if abs(lat) <= lim:
        return None
    return (f"site.latitude_deg = {lat:g}: gyrocompass alignment is refused beyond "
            f"|latitude| {lim:.2f} deg, where the horizontal Earth rate leaves the gyros' "
            f"noise an azimuth sigma above {AZIMUTH_SIGMA_LIMIT_DEG:g} deg (use the mirror "
            "alignment)")


def day_alignments(st: IsuDrivers, run: Run, calib: CalibrationResults, cfg: StationConfig,
                   world: World | None,
                   tape_dir: Path | None = None, plan: AlignPlan | None = None,
                   samples_dir: Path | None = None,
                   library: TapeLibrary | None = None) -> list[dict]:
    """After the calibration of ``station day``: the three alignments (those the
    calibration allows, ``day_methods``), as results entries. The gyrocompass alignment
    is skipped near a pole (``gyrocompass_refusal``), its entry saying why. ``plan``: the
    config's ``[alignment]`` when None; ``library``: the tape library (None: none)."""
    plan = plan or cfg.alignment.plan()
    methods = day_methods(calib)
    skipped = []
    if plan.accels != (1, 2, 3) or plan.gyros != (1, 2, 3):  # reduced sets: simple average
        for method in ("level", "gyrocompass"):
            if method not in methods:
                continue
            if (why := plan.reduced_refusal(method)) is not None:
                methods.pop(method)
                skipped.append({"method": method, "skipped": f"alignment.{why}"})
            else:
                methods[method] = ("average",)
    why = gyrocompass_refusal(cfg, plan)
    if "gyrocompass" in methods and why is not None:
        methods.pop("gyrocompass")
        skipped.append({"method": "gyrocompass", "skipped": why})
    opts = AlignmentOptions(noise=noise_spec(cfg), calib=calib, site=site_of(cfg),
                            plan=plan, estimators=methods, tape_dir=tape_dir,
                            calibration_id="this run (Chart II-15)", library=library)
    outcomes = run_alignments(st, run, opts)
    if samples_dir is not None:  # the raw IEU samples of each alignment as CSV
        write_alignment_samples(samples_dir, outcomes)
    return judge_alignments(alignment_entries(outcomes, world), cfg.limits) + skipped


def _sheet(f: Path, model: type[T]) -> T:
    try:
        return model.model_validate_json(f.read_bytes())
    except OSError as e:
        raise ValueError(f"{f}: cannot read it ({e.strerror})") from None
    except ValidationError as e:
        err = e.errors()[0]
        where = ".".join(str(x) for x in err["loc"]) or "(top)"
        raise ValueError(f"{f}: not a {model.__name__} sheet: {where}: {err['msg']}") from None


def load_calibration(d: Path) -> tuple[CalibrationResults, SurveyResults | None]:
    """Calibration Results (and Survey Results) sheets of an earlier run directory."""
    d = Path(d)
    if not d.is_dir():
        raise FileNotFoundError(f"--calibration {d}: no such directory")
    sheets = d / "sheets"
    f = sheets / "calibration_results.json"
    if not f.is_file():
        raise FileNotFoundError(f"--calibration {d}: no Calibration Results Sheet in "
                                f"{sheets} (run station day)")
    calib = _sheet(f, CalibrationResults)
    s = sheets / "survey_results.json"
    survey = _sheet(s, SurveyResults) if s.is_file() else None
    return calib, survey


def load_tape(path: Path) -> Tape:
    """A parameter tape file; ValueError naming it when it is not one."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"tape {path}: no such file")
    return _sheet(path, Tape)


# `station align` options per method: the plan's field for the level and gyrocompass record.
RECORD_OPTIONS = {"K": ("level_K", "gyro_K"), "dt": ("level_dt_s", "gyro_dt_s"),
                  "ieu_period": ("level_period_s", "gyro_period_s")}
OPTION_NAMES = {"K": "--K", "dt": "--dt", "ieu_period": "--ieu-period", "eps_t_s": "--eps-t",
                "sigma_g_g": "--sigma-g", "sigma_theta_arcsec": "--sigma-theta",
                "mirror_readings": "--mirror-readings", "alpha_readings": "--alpha-readings",
                "mirror_zenith": "--theta1", "surveyed_g": "--surveyed-g",
                "surveyed_earth_rate": "--surveyed-earth-rate",
                "known_colatitude": "--known-colatitude", "prior_attitude": "--prior-attitude",
                "quick_K": "--quick-K", "accels": "--accels", "gyros": "--gyros"}


def command_plan(cfg: StationConfig, method: str, given: dict[str, Any]) -> AlignPlan:
    """The config's ``[alignment]`` plan with the command line's choices (None: not given);
    ValueError naming the option when the plan it makes is not one."""
    given = {k: v for k, v in given.items() if v is not None}
    update: dict[str, Any] = {}
    for name, value in given.items():
        if name in RECORD_OPTIONS:
            if method == "mirror":
                raise ValueError(f"{OPTION_NAMES[name]}: the mirror alignment takes no IEU "
                                 "record (K, Delta t and the IEU period are level and "
                                 "gyrocompass choices)")
            update[RECORD_OPTIONS[name][method == "gyrocompass"]] = value
        else:
            update[name] = value
    try:
        plan = AlignPlan.model_validate(cfg.alignment.plan().model_dump() | update)
    except ValidationError as e:
        err = e.errors()[0]
        field_name = str(err["loc"][0]) if err["loc"] else ""
        opt = next((OPTION_NAMES[k] for k, v in RECORD_OPTIONS.items() if field_name in v),
                   OPTION_NAMES.get(field_name, "--dt / --ieu-period"))
        raise ValueError(f"{opt}: {err['msg'].removeprefix('Value error, ')}") from None
    why = plan.reduced_refusal(method)
    if why is not None:
        raise ValueError(f"--{why.split(':')[0].replace('/', ' / --')}:{why.split(':', 1)[1]}")
    limit = cfg.instruments.ieu.max_period_s
    for name in ("level_period_s", "gyro_period_s"):
        if getattr(plan, name) > limit:
            raise ValueError(f"--ieu-period: {getattr(plan, name):g} s is longer than the "
                             f"IEU's instruments.ieu.max_period_s = {limit:g} s")
    return plan


def check_tape_plan(tape: Tape, plan: AlignPlan, method: str, path: Path) -> None:
    """The tape's K, Delta t, eps_t, sigma_g and sigma_theta against the plan, before the
    run starts (the inputs the survey and calibration give are checked at Chart III-4
    step 8 / III-8 step 7); ValueError naming the parameter."""
    K, dt = ((plan.gyro_K, plan.gyro_dt_s) if method == "gyrocompass"
             else (plan.level_K, plan.level_dt_s))
    p = tape.params
    for name, got, want in (("K", p.K, K), ("dt", p.dt, dt), ("eps_t", p.eps_t, plan.eps_t_s),
                            ("sigma_g", p.sigma_g, plan.sigma_g_g * es.G0),
                            ("sigma_theta", p.sigma_theta, plan.sigma_theta_arcsec * ARCSEC)):
        if not math.isclose(got, want, rel_tol=1e-9):
            raise ValueError(f"--tape {path}: tape parameter {name} differs from the "
                             f"experiment's: tape {got:.6g}, experiment {want:.6g}")


def tape_library(cfg: StationConfig, override: Path | None, run_uid: str
                 ) -> TapeLibrary | None:
    """The run's tape library: ``override`` (--tape-library), else the config's."""
    root = override if override is not None else cfg.alignment.tape_library
    return None if root is None else TapeLibrary(Path(root), run_uid)


def render_alignment(console: Console, entries: list[dict]) -> None:
    """Chart III-1's rows on the console (split rather than cut when narrow)."""
    names = ("method", "technique", "K x dt", "about E", "about N", "azimuth",
             "sigma E/N/az", "limit E/N/az")
    cols = [Column(c, right=c not in ("method", "technique")) for c in names]
    skipped = [e for e in entries if "skipped" in e]
    cells = []
    for e in entries:
        if "skipped" in e:
            continue
        z = e["error_over_sigma"]

        def f(x: float | None, zz: float) -> str:  # zz: x over its sigma (given with x)
            if x is None:
                return "-"
            s = f"{x:+.2f}"
            return f"[red]{s}[/]" if abs(zz) > 4 else s

        cells.append([e["method"], e["estimator"], f"{e['K']} x {e['dt']:g} s",
                      f(e["level_error_arcsec"][0], z[0]), f(e["level_error_arcsec"][1], z[1]),
                      f(e["azimuth_error_arcsec"], z[2]),
                      "/".join(f"{x:.2f}" for x in e["predicted_sigma_arcsec"]),
                      "/".join(f"{x:.2f}" for x in e["physical_limit_arcsec"])])
    print_fitted(console, "Alignment Results (Chart III-1): error vs truth, predicted sigma, "
                 "physical limit (arcsec)", cols, cells)
    for e in skipped:
        console.print(f"{e['method']} alignment skipped: {e['skipped']}", markup=False)


@dataclass(frozen=True)
class AlignRequest:
    """One `station align` run: which alignment, after which calibration, where, and how.

    ``method``: mirror | level | gyrocompass; ``estimator``: average | posterior | hybrid
    (level's hybrid is its posterior mean, the gyrocompass's posterior mean its hybrid).
    ``calibration``: a run directory whose Calibration Results (and Survey Results) sheets
    to use; None: a full calibration day is measured first in the same run. ``tape``: a
    parameter tape to use instead of producing one (checked against the experiment: a
    mismatch stops Chart III-4 step 8 / III-8 step 7 naming the parameter). ``tape_library``:
    the library tapes are taken from and filed to (None: the config's ``[alignment]
    tape_library``, if any). ``plan``: the alignment plan (K, Delta t, IEU period, options;
    None: the config's ``[alignment]``). ``warmup_s``: the turn-on warm-up
    after an earlier calibration (default the day plan's). ``links``: run over the links of
    a rack served under that directory (real time). ``resume``: continue the interrupted
    alignment in ``out``. ``quiet``: no live display.
    """

    cfg: StationConfig
    out: Path
    method: str
    estimator: str = "average"
    calibration: Path | None = None
    tape: Path | None = None
    tape_library: Path | None = None
    plan: AlignPlan | None = None
    warmup_s: float | None = None
    links: Path | None = None
    resume: bool = False
    quiet: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "out", Path(self.out))


def run_align(req: AlignRequest, console: Console | None = None,
              rack_hook: Callable[[SimulatedRack], None] | None = None) -> dict:
    """The one alignment ``req`` asks for into ``req.out``; returns the results dict (also
    ``out/results.json``). ``rack_hook`` may inject faults into the simulated rack before
    anything runs.

    Every field of the request, the sheets and the tape are checked before anything is
    written (ValueError, FileNotFoundError, RunDirError); a gyrocompass alignment near a
    pole is refused (``gyrocompass_refusal``).
    """
    cfg, method, estimator = req.cfg, req.method, req.estimator
    plan = req.plan or cfg.alignment.plan()
    calibration_dir, links, out = req.calibration, req.links, req.out
    est = canonical_estimator(method, estimator)
    if method == "gyrocompass" and (why := gyrocompass_refusal(cfg, plan)) is not None:
        raise ValueError(why)
    console = shown_console(console, req.quiet)
    day_plan = DayPlan()
    calib = survey = None
    if calibration_dir is not None:
        calib, survey = load_calibration(calibration_dir)
    tapes = {}
    if req.tape is not None:
        tapes = {method: load_tape(req.tape)}
        check_tape_plan(tapes[method], plan, method, req.tape)
    prepare(out, req.resume, links)
    wall0 = time.perf_counter()
    conn = connect(registry.get("isu"), cfg, links, rack_hook)
    st = conn.station
    site = site_of(cfg)
    noise = noise_spec(cfg)
    try:
        with opened_journal(out, req.resume) as journal, ExitStack() as stack:
            stack.callback(report_after, out)  # after run.json closes; not for a refused run
            stack.callback(index_after, out)  # history: after run.json closes
            ident = stack.enter_context(identified(
                out, "isu", "align", cfg.seed, isu_config(cfg), *isu_identity(cfg),
                req.resume, journal.records))
            with can_log(out, st.ieu), DayDisplay(console) as display:
                run = Run(st.clock, journal, listener=display,
                          resume="replay" if conn.rack is not None else "skip",
                          sheet_models=ISU_SHEETS, sheets_used=sheets_used,
                          header=ident.header(f"{method} alignment (station align)",
                                              ident.record["unit"]["isu"]))
                if req.resume:
                    resume_note(run)
                run.note(event="start", run_uid=ident.run_uid, seed=cfg.seed,
                         command="align", method=method,
                         estimator=est, estimator_requested=estimator,
                         calibration=str(calibration_dir) if calibration_dir else None,
                         tape=None if req.tape is None else str(req.tape),
                         tape_library=None if req.tape_library is None
                         else str(req.tape_library),
                         plan=plan.model_dump(),
                         session=conn.session.session if conn.session else None)
                if calib is None:
                    data = measure_day(st, run, day_plan, site, cfg.isu.accels[0].f0_hz,
                                       noise=noise)
                    calib = compute_calibration(run, data, day_plan, noise,
                                                site)
                    survey = data.survey
                    cal_id = "this run (Chart II-15)"
                    write_day_calibration(out, calib, cfg, data, day_plan, site, noise)
                else:
                    turn_on(st, run, day_plan.warmup_s if req.warmup_s is None
                            else req.warmup_s)
                    cal_id = str(calibration_dir)
                opts = AlignmentOptions(noise=noise, calib=calib, survey=survey, site=site,
                                        plan=plan, estimators={method: (est,)}, tapes=tapes,
                                        tape_dir=out / "tapes", calibration_id=cal_id,
                                        library=tape_library(cfg, req.tape_library,
                                                             ident.run_uid))
                outcomes = run_alignments(st, run, opts)
            write_sheets(out, run)
            entries = judge_alignments(alignment_entries(outcomes, conn.attitude_world),
                                       cfg.limits)
            res = {
                "seed": cfg.seed,
                "sim_seconds": st.clock.now(),
                "wall_seconds": time.perf_counter() - wall0,
                "calibration": cal_id,
                "estimator_requested": estimator,
                "alignment": entries,
                "links": None if links is None else str(links),
                "verdict": run_verdict(entries),
            }
            write_results(out, res)
            write_results_csv(out, entries)
            write_alignment_samples(out, outcomes)
            run.note(event="end", sim_seconds=st.clock.now())
        if console is not None:
            render_alignment(console, entries)
            if est != estimator:
                console.print(f"note: {method} alignment with the {estimator} technique is "
                              f"the {est} technique (Charts III-6, III-10)")
        return res
    finally:
        conn.close()
