"""`station esg-calibration`: the ESG readout laboratory (report 004) in virtual time.

Runs the acquisition (steps 1-13), reduces it under the report's two calibration
schedules, adds what only the simulator knows (the true colatitude of pickoff 2 at every
reading), runs the readout strategy study (Figure 2) and writes journal, sheets, tables,
plots and esg.json.

With ``links`` (``--links DIR``) the same procedure and drivers run against a rack served
by ``station serve --station esg --links DIR``, over its ptys and on a WallClock on the
rack's time. The true colatitude at each reading depends on the path the served rotor and
mount took, which only the server knows: those columns are None in a served run. The one
static truth, pickoff 1's coning in the case, comes from a rack built here with the run's
seed and params (never run), and only when the served session has that seed and config
digest.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from laboratory import registry
from laboratory.connect import connect, journaled_run
from laboratory.esg.plot_child import PLOTS, STRATEGY, STUDY, VARIANTS
from laboratory.esg.plots import GOAL_ARCSEC, schedule_plot
from laboratory.esg.study import (  # noqa: F401 - re-exported
    REPORT_POINTS,
    STUDY_POINTS,
    STUDY_RANGES,
    study,
)
from laboratory.esg.truth import true_pickoff1_coning_arcsec
from laboratory.export import write_results_csv
from laboratory.identity import Identifying
from laboratory.plot_worker import PlotWorker
from laboratory.record import write_json, write_sheets
from laboratory.rundir import prepare
from laboratory.seeded import Seeded
from laboratory.shown import Shown
from laboratory.tables import Column, print_fitted
from laboratory.verdicts import judge_schedules, run_verdict
from procedures.esg.acquisition import RENEW, Acquisition, EsgPlan, acquire
from procedures.esg.calibration import SCHEDULES, ScheduleResult, assign, calibrate, nominal
from procedures.esg.cosine import CosineParams
from procedures.esg.mechanization import Mechanization
from procedures.esg.pickoff3 import pickoff3_alignment
from procedures.esg.pickoff3_mirror2 import pickoff3_both
from procedures.esg.remount import pickoff2_alignment
from procedures.esg.table4 import REPORT_ORDER, order_trials, table4
from sim.esg.pattern import PatternSpec, nominal_pattern
from sim.esg.world import EsgParams, EsgWorld
from station.config.esg import EsgConfig, ProcedureConfig
from station.config.limits import EsgLimits
from station.racks.esg import EsgRack

if TYPE_CHECKING:
    from rich.console import Console



def _rms(values: Iterable[float | None]) -> float:
    v = [x for x in values if x is not None]
    return math.sqrt(sum(x * x for x in v) / len(v)) if v else float("nan")


def add_truth(rows: list[dict], world: EsgWorld, acq: Acquisition,
              times: dict[tuple[str, float], list[float]]) -> None:
    """True colatitude of pickoff 2 (mean over the reading's lines) and the true error."""
    for r in rows:
        ts = times[(r["scan"], r["offset_deg"])]
        th = [math.degrees(float(world.true_colatitudes(t + acq.t_zero_s)[1])) for t in ts]
        r["true_colatitude_deg"] = sum(th) / len(th)
        r["true_error_arcsec"] = (r["compensated_deg"] - r["true_colatitude_deg"]) * 3600.0
        r["assignment_error_arcsec"] = (r["colatitude_deg"] - r["true_colatitude_deg"]) * 3600


def no_truth(rows: list[dict]) -> None:
    """The truth columns, absent (a served run: the served world's path is not known here)."""
    for r in rows:
        r["true_colatitude_deg"] = None
        r["true_error_arcsec"] = None
        r["assignment_error_arcsec"] = None


def _rms_known(values: Iterable[float | None]) -> float | None:
    """rms of the values present; None if there are none (truth absent)."""
    v = [x for x in values if x is not None]
    return _rms(v) if v else None


def schedule_summary(res: ScheduleResult) -> dict:
    cal, rd = res.calibration, res.readout
    return {
        "name": res.name, "order": res.fit.order,
        "calibration_rms_arcsec": _rms([r["error_arcsec"] for r in cal]),
        "readout_rms_arcsec": _rms([r["error_arcsec"] for r in rd]),
        "true_calibration_rms_arcsec": _rms_known([r["true_error_arcsec"] for r in cal]),
        "true_readout_rms_arcsec": _rms_known([r["true_error_arcsec"] for r in rd]),
        "assignment_rms_arcsec": _rms_known([r["assignment_error_arcsec"] for r in cal + rd]),
        "predicted_assignment_rms_arcsec": _rms([r["sigma_assign_arcsec"] for r in cal + rd]),
        "max_readout_error_arcsec": max((abs(r["error_arcsec"]) for r in rd), default=None),
        "n_fit": len(cal), "n_readout": len(rd),
        "chebyshev": [float(c) for c in res.fit.coef],
        "power_p0_p7": [float(c) for c in res.fit.power],
    }


def used_order(trials: list[dict], schedule: str, order: int | str) -> int:
    """The order a schedule is reduced with: ``order``, or the trials' choice by the
    residuals when ``order`` is "residuals"."""
    if order == "residuals":
        return next(int(t["order"]) for t in trials
                    if t["schedule"] == schedule and t["chosen_by_residuals"])
    return int(order)


def render_tables(console: Console, res: dict) -> None:
    """Schedules (Table 4 of the report) and the strategy study's report points, with rich."""
    from rich import box
    from rich.table import Table

    def f1(x: float | None) -> str:
        return "-" if x is None else f"{x:.1f}"

    def f2(x: float | None) -> str:
        return "-" if x is None else f"{x:.2f}"

    names = ("schedule", "n fit", "calibration", "true", "n readout", "readout", "true",
             "assignment", "predicted")
    cells = [[s["name"], str(s["n_fit"]), f1(s["calibration_rms_arcsec"]),
              f1(s["true_calibration_rms_arcsec"]), str(s["n_readout"]),
              f1(s["readout_rms_arcsec"]), f1(s["true_readout_rms_arcsec"]),
              f1(s["assignment_rms_arcsec"]), f1(s["predicted_assignment_rms_arcsec"])]
             for s in res["schedules"]]
    print_fitted(console, "Pattern calibration and readout (arcsec rms; true = against the "
                 "simulator's colatitude)", [Column(c) for c in names], cells, keys=1)
    if "table4" in res:
        print_fitted(console, f"Table 4: calibration and readout errors (arcsec; largest / "
                     f"{GOAL_ARCSEC:g} arcsec goal; true = against the simulator)",
                     [Column(c) for c in ("schedule", "data", "order", "n", "rms",
                                          "avg |e|", "largest", "/goal", "true rms",
                                          "true avg", "true largest")],
                     [[t["schedule"], t["data"], str(t["order"]), str(t["n"]),
                       f1(t["rms_arcsec"]), f1(t["mean_abs_arcsec"]), f1(t["largest_arcsec"]),
                       f2(t["largest_over_goal"]), f1(t["true_rms_arcsec"]),
                       f1(t["true_mean_abs_arcsec"]), f1(t["true_largest_arcsec"])]
                      for t in res["table4"]], keys=2)
    if "order_trials" in res:
        print_fitted(console, "Polynomial order trials, 5th to 9th (arcsec rms; * = the "
                     "choice by the prediction residuals)",
                     [Column(c) for c in ("schedule", "order", "fit sigma", "prediction",
                                          "calibration", "readout", "true cal",
                                          "true readout")],
                     [[t["schedule"], f"{t['order']}{'*' if t['chosen_by_residuals'] else ''}",
                       f1(t["residual_sigma_arcsec"]), f1(t["prediction_rms_arcsec"]),
                       f1(t["calibration_rms_arcsec"]), f1(t["readout_rms_arcsec"]),
                       f1(t["true_calibration_rms_arcsec"]), f1(t["true_readout_rms_arcsec"])]
                      for t in res["order_trials"]], keys=2)
    if "amplification" in res:
        a = Table(title="Edge-error amplification (Figure 2 points)", box=box.SIMPLE_HEAD)
        for c in ("pattern", "range", "strategy", "factor", "report"):
            a.add_column(c, justify="right")
        rep = {("great_circle", 43.0): "1.55", ("cosine", 37.0): "1.20"}
        for r in res["amplification"]:
            a.add_row(r["pattern"], f"{r['range_deg']:g}", r["strategy"],
                      f"{r['factor']:.3f}", rep[(r["pattern"], r["range_deg"])]
                      if r["strategy"] == "mixed" else "")
        console.print(a)
    if "strategy_variants" in res:
        sv = res["strategy_variants"]
        factor = {(r["pattern"], r["sets"], r["pickoffs"], r["strategy"]): r["factor"]
                  for r in sv["table"]}
        arrangements = [(n, p) for n in (1, 2) for p in ("three orthogonal",
                                                         "four tetrahedral")]
        print_fitted(console, f"Strategy variants at {sv['range_deg']:g} deg (RMS "
                     "amplification, mixed / two-pickoff)",
                     [Column("pattern")] + [Column(f"{n} set{'s' if n > 1 else ''}, {p}")
                                            for n, p in arrangements],
                     [[pat] + [f"{factor[(pat, n, p, 'mixed')]:.3f} / "
                               f"{factor[(pat, n, p, 'two_pickoff')]:.3f}"
                               for n, p in arrangements]
                      for pat in dict.fromkeys(r["pattern"] for r in sv["table"])], keys=1)


def calibration_plot(results: list[ScheduleResult], path: Path) -> None:
    """Compensated minus assigned (or true) colatitude per schedule (laboratory.esg.plots)."""
    schedule_plot(plain_schedules(results), path)


def drawing(spec: PatternSpec) -> dict:
    """The plan's pattern drawing from the rotor's spec: kind, inclination (great circle),
    K (cosine), the lines' end, and the last whole-degree scan offset inside it."""
    return {"pattern_kind": spec.kind, "design_inclination_deg": spec.inclination_deg,
            "design_cosine_k": nominal_pattern(spec).k if spec.kind == "cosine" else 0.0,
            "design_top_deg": spec.top_colatitude_deg,
            "scan_end_deg": math.floor(89.0 - spec.top_colatitude_deg)}


def lab_spec(params: EsgParams, revolutions: int) -> dict:
    """What the plan takes from the gyro's and the processor's specification: the electric
    torque's drift (the drift budget's bound) and the line-to-line count-ratio scatter.
    A line's C1 sums ``revolutions`` start-stop intervals, two jittered trailing edges
    each, over as many periods 1 / spin: sigma(CR) = sqrt(2 / revolutions) jitter spin
    (80 ns at 250 rps, ten revolutions: 8.9e-6, Appendix A's 9e-6)."""
    return {"electric_drift_spec_deg_hr": params.rotor.electric_deg_h,
            "line_scatter_spec": math.sqrt(2.0 / revolutions) * params.signal.jitter_ns * 1e-9
            * params.rotor.spin_rps}


def mechanization_record(nom: Mechanization) -> dict:
    """The nominal mechanization as esg.json keeps it."""
    if isinstance(nom, CosineParams):
        return {"kind": "cosine", "k": nom.k, "d0": nom.d0}
    return {"b": nom.b, "c": nom.c, "dbar": nom.dbar, "inclination_deg": nom.inclination_deg}


def procedure_record(plan: EsgPlan, variants_points: int | None) -> dict:
    """The run's ``[esg.procedure]`` settings as config.toml keeps them: those that differ
    from the defaults (a default run's table stays empty; absent fields are defaults)."""
    used = {"extremity_setup": plan.extremity_setup, "counters": plan.counters,
            "strategy_variants": variants_points is not None,
            "adjust_alignment": plan.adjust_alignment,
            "alignment_iterations": plan.alignment_iterations,
            "remount_alignment": plan.remount_alignment,
            "pickoff3_mirror2": plan.pickoff3_mirror2}
    if variants_points is not None:
        used["strategy_variants_points"] = variants_points
    default = ProcedureConfig.model_validate({}).model_dump()
    return {k: v for k, v in used.items() if v != default[k]}


def plain_schedules(results: list[ScheduleResult]) -> list[dict]:
    """What the schedule plot draws of each schedule, as plain data for the plot child."""
    return [{"name": r.name, "calibration": r.calibration, "readout": r.readout}
            for r in results]


def run_esg_calibration(seed: int, out: Path, params: EsgParams | None = None,
                        plan: EsgPlan | None = None,
                        rack_hook: Callable[[EsgRack], None] | None = None,
                        with_study: bool = True, links: Path | None = None,
                        resume: bool = False, limits: EsgLimits | None = None,
                        order: int | str = REPORT_ORDER,
                        variants_points: int | None = None,
                        show: Shown | None = None) -> dict:
    """The whole ESG calibration into ``out``; ``rack_hook`` may inject faults.

    ``links``: run against the ESG rack served there instead (see the module doc);
    raises ``NoServedRack`` or ``WrongStation`` (both OSError/ValueError) if it is not.
    ``resume``: continue the interrupted calibration in ``out`` (replayed and checked
    against its journal in virtual time); ``out`` must hold no record otherwise.
    ``limits``: the acceptance limits (default: the readout goal, station/config/limits.py).
    ``order``: the eq. 11 polynomial order used (5..9; the report's 7), or "residuals" for
    each schedule's choice by the order trials' residuals; every order from 5 to 9 is
    tried and tabulated whatever is used ("Data Reduction Technique").
    ``variants_points``: the strategy study's variants and Figure 3 (esg_figure3.png)
    added to the record, averaged over that many orientations (None: not computed).
    ``show``: the command's display of the results, called with them while the last plot
    is drawn (issue 17: the child's plot, not the display, is then what the run waits for).
    """
    out = Path(out)
    params = params or EsgParams()
    plan = plan or EsgPlan(latitude_deg=0.0)
    plan = replace(plan, latitude_deg=params.latitude_deg, counters=params.counters,
                   **drawing(params.pattern), **lab_spec(params, plan.revolutions))
    prepare(out, resume, links)
    wall0 = time.perf_counter()
    conn = connect(registry.get("esg"), Seeded(params, seed), links, rack_hook)
    st, served, world = conn.drivers, conn.served, conn.coefficient_world
    child = (PLOTS, STUDY, STRATEGY) + ((VARIANTS,) if variants_points is not None else ())
    procedure = procedure_record(plan, variants_points)
    with PlotWorker(*child) as plots, journaled_run(  # matplotlib meanwhile
            out, conn, resume, renew=RENEW, seed=seed, test="esg-calibration", order=order,
            extremity_setup=plan.extremity_setup, counters=plan.counters,
            **{k: True for k in ("strategy_variants", "adjust_alignment",
                                      "remount_alignment", "pickoff3_mirror2")
               if procedure.get(k)},
            identify=Identifying("esg", "esg-calibration", seed, "esg", EsgConfig, params,
                                 tables={"procedure": procedure})) as (
            run, extra, t_start):
        if with_study:  # the study needs no measurement: computed and drawn during the run
            studied = plots.draw([(f"{STUDY}:study_plot", {"path": out / "esg_strategy.png"})],
                                 more=True)
        if variants_points is not None:  # the same, for the variants and Figure 3
            varied = plots.draw([(f"{VARIANTS}:variants_plot",
                                  {"path": out / "esg_figure3.png", "points": variants_points})],
                                more=True)
        acq = acquire(st, run, plan, pickoff2_alignment,
                      pickoff3_both if plan.pickoff3_mirror2 else pickoff3_alignment)
        points, bud = assign(acq, plan, plan.lines_per_setting)
        times = {(p.scan, p.offset_deg): p.times_s for p in points}
        nom = nominal(acq, plan)
        def truth(res: ScheduleResult) -> None:
            if served is None:
                add_truth(res.calibration, world, acq, times)
                add_truth(res.readout, world, acq, times)
            else:
                no_truth(res.calibration)
                no_truth(res.readout)

        def reduced(trials: list[dict]) -> list[ScheduleResult]:
            """Each schedule reduced at its order, its truth added, and sent to be drawn."""
            out_ = [calibrate(points, nom, s, order=used_order(trials, s, order))
                    for s in SCHEDULES]
            for res in out_:
                truth(res)
            plots.draw([(f"{PLOTS}:schedule_plot", {"schedules": plain_schedules(out_),
                                                     "path": out / "esg_calibration.png"})])
            return out_

        # a fixed order needs no trial: the schedules are drawn while the trials run
        results = None if order == "residuals" else reduced([])
        trials = order_trials(points, nom, SCHEDULES, truth, goal_arcsec=GOAL_ARCSEC)
        run.save_sheet("esg_order_trials", trials)
        results = results if results is not None else reduced(trials)
        for res in results:
            run.save_sheet(f"esg_calibration_{res.name}", res.calibration)
            run.save_sheet(f"esg_readout_{res.name}", res.readout)
        schedules = judge_schedules([schedule_summary(r) for r in results],
                                    limits or EsgLimits())
        run.save_sheet("esg_schedules", schedules)
        tab4 = table4(results, GOAL_ARCSEC)
        run.save_sheet("esg_table4", tab4)
        res_json = {
            "seed": seed,
            "schedules": schedules,
            "table4": tab4,
            "order_trials": trials,
            "nominal": mechanization_record(nom),
            "acquisition": {
                "cr_a": acq.cr_a, "cr_b": acq.cr_b, "cr_eq": acq.cr_eq,
                "theta_star_deg": acq.theta_star_deg,
                "equal_points_separation_deg": acq.gamma_b_deg - acq.gamma_a_deg,
                "unbalance_k_deg_hr": acq.unbalance_k_deg_hr,
                "residual_drift_deg_hr": acq.residual_drift_deg_hr,
                "mount_coning_arcsec": acq.mount_coning_arcsec,
                "pickoff_coning_arcsec": acq.pickoff_coning_arcsec,
                "true_pickoff_coning_arcsec": true_pickoff1_coning_arcsec(world)
                if world is not None else None,
                "scans": len(acq.scans), "points": len(points)},
            "budget": {"slope_per_deg": bud.slope_per_deg, "line_sigma": bud.line_sigma,
                       "equator_arcsec": bud.equator_deg * 3600.0,
                       "head_arcsec": bud.head_deg * 3600.0,
                       "drift_bound_deg_hr": bud.drift_bound_deg_s * 3600.0},
            "goal_arcsec": GOAL_ARCSEC,
            "verdict": run_verdict(schedules),
            **extra,
        }
        if with_study:
            curve, amp, edge = plots.values(studied)[0]
            res_json["amplification"] = amp
            res_json["amplification_curve"] = curve
            res_json["edge_resolution"] = edge
            run.save_sheet("esg_strategy", curve)
        if variants_points is not None:
            res_json["strategy_variants"] = plots.values(varied)[0]
            run.save_sheet("esg_strategy_variants", res_json["strategy_variants"]["table"])
            run.save_sheet("esg_figure3", res_json["strategy_variants"]["figure3"])
        write_sheets(out, run)
        res_json["sim_seconds"] = st.clock.now() - t_start
        res_json["wall_seconds"] = time.perf_counter() - wall0
        write_json(out / "esg.json", res_json)
        write_results_csv(out, schedules, "esg.csv")
        plots.wait(meanwhile=lambda: (show or Shown(None)).meanwhile(res_json))
        run.note(event="end", sim_seconds=st.clock.now() - t_start)
        return res_json
