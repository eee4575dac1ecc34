"""The full calibration day of report 000, Parts I and II, in the laboratory's order.

Turn-on (I-1), system survey (I-2), resolver and counter settings (II-6), the measurement
check-sheets (II-6, II-7, II-7Q, II-10, II-11, II-12, II-13, II-14; II-14E, the extra
accelerometer positions beyond the manual, when ``[calibration] extra_accel_tilts_deg``
asks) and the calibration computations (II-15). ``only`` restricts the measurements to some
charts (turn-on and survey always run: everything needs them); the computations then give
exactly what Chart II-16 allows from the positions measured."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from procedures.isu import settings as st_settings
from procedures.isu import simultaneous as sim
from procedures.isu.accel_static import accel_positions_7_12, accel_positions_13_14
from procedures.isu.bubble import uncorrected_for
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.extra_positions import extra_accel_positions
from procedures.isu.gyro_rotating import scale_factor_positions
from procedures.isu.gyro_static import gyro_positions_7_12, gyro_positions_13_15
from procedures.isu.j_term import j_experiment
from procedures.isu.nonlinearity import nonlinearity_experiment, q_is_experiment
from procedures.isu.plan import DayPlan
from procedures.isu.positions import resolver_settings
from procedures.isu.sheets import CounterOutputs, SurveyResults
from procedures.isu.site import Site
from procedures.isu.system_survey import system_survey
from procedures.isu.turn_on import oscillator_periods, turn_on
from procedures.runner import Run

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

EXPERIMENTS = ("II-6", "II-7", "II-7Q", "II-10", "II-11", "II-12", "II-13", "II-14", "II-14E")


@dataclass
class DayData:
    """Everything measured: the inputs of the calibration computations."""

    survey: SurveyResults | None
    s1: float
    f0: float
    gyro: dict[int, dict] = field(default_factory=dict)
    accel: dict[int, dict] = field(default_factory=dict)
    nonlinearity: dict[int, list[dict]] = field(default_factory=dict)
    q_is: dict[int, list[dict]] = field(default_factory=dict)
    j_term: dict[int, list[dict]] = field(default_factory=dict)
    extra_accel: dict[int, dict] = field(default_factory=dict)  # II-14E: 16 on (issue 19)


def _by_position(d: dict) -> dict[int, Any]:
    """A journaled {position: ...} mapping (JSON keys are strings) with integer keys again."""
    return {int(k): v for k, v in d.items()}


def chart_data(block: dict) -> dict[int, Any]:
    """A measurement chart's data, by position, from its block's journal form (what
    ``measure_day`` keeps of it, and what a run's listener hears as soon as it is run)."""
    return _by_position(block["data"])


def _pairs(first: tuple[int, ...], positions: set[int] | None) -> tuple[int, ...]:
    """The pairs (m, m + 1) that hold a wanted position: a pair is measured whole."""
    return tuple(m for m in first if positions is None or {m, m + 1} & positions)


def _singles(all_: tuple[int, ...], positions: set[int] | None) -> tuple[int, ...]:
    return tuple(m for m in all_ if positions is None or m in positions)


def measure_day(st: IsuDrivers, run: Run, plan: DayPlan, site: Site, f0: float,
                only: tuple[str, ...] | None = None,
                positions: tuple[int, ...] | None = None,
                noise: NoiseSpec | None = None,
                survey: SurveyResults | None = None) -> DayData:
    """Turn-on, survey, settings and the measurement check-sheets; returns the data.

    ``positions`` restricts the position charts (II-6, II-11..II-14) to those positions; a
    position of a pair (m, m + 1, the second reached by turning phi3) brings its pair.
    Every chart is a journaled block (``Run.block``), so a resume over links restores the
    charts already completed and repeats only the interrupted one. ``noise``: the lab's
    specification, which the survey's agreement checks judge its readings by (default:
    ``NoiseSpec``'s defaults, the default lab's). ``site``: what Chart I-2 step 3 records.
    ``survey``: an earlier Survey Results Sheet used instead of running Chart I-2.
    """
    wanted = set(EXPERIMENTS if not only else only)
    unknown = wanted - set(EXPERIMENTS) - {"I-1", "I-2"}
    if unknown:
        raise ValueError(f"unknown chart(s) {sorted(unknown)}; choose from {EXPERIMENTS}")
    pos = None if positions is None else set(positions)
    if pos is not None and not pos <= set(range(1, 16)):
        raise ValueError(f"unknown position(s) {sorted(pos - set(range(1, 16)))}; "
                         "calibration positions are 1 to 15")
    need = set(range(1, plan.options.counters + 1))
    if plan.options.simultaneous and not need <= set(st.counters):
        raise ValueError(f"[calibration] counters = {plan.options.counters}: the station has "
                         f"counters {', '.join(map(str, sorted(st.counters)))} only (a served "
                         "rack serves report 000's six)")
    run.block("I-1", lambda: turn_on(st, run, plan.warmup_s), lambda _: None)
    t_survey: float | None = None  # the survey's level reading, as near as the day knows
    if survey is None:
        survey = run.block("I-2", lambda: system_survey(st, run, site, noise=noise),
                           SurveyResults.model_validate)
        t_survey = st.clock.now()
    else:
        run.save_sheet("survey_results", survey)
    unc = uncorrected_for(plan, survey, t_survey)  # II-6.1: bubble corrections or not
    gate = plan.options.gyro_gate  # II-5.2: clock gate, or the time for a preset of pulses
    prec = {"G": plan.options.precision_gyro_arcsec, "A": plan.options.precision_accel_arcsec}
    s1, _ = oscillator_periods(run)  # as Chart I-1 step 3 read them (twice, agreeing)
    settings = resolver_settings(survey)
    run.save_sheet("resolver_settings", settings)
    connections = st_settings.counter_connections()
    if plan.options.simultaneous:  # II-5: the experiment the extra counters allow
        connections.experiments[st_settings.SIMULTANEOUS] = (
            st_settings.simultaneous_connections(plan.options.counters))
    run.save_sheet("counter_connections", connections)
    times, gates = st_settings.collection_times(plan, site, noise or NoiseSpec(), s1, f0,
                                                survey.t_bi)
    gyro_gate_s, acc_v_s, acc_h_s = times.gyro_s, times.accel_vertical_s, times.accel_horizontal_s
    plan = plan.model_copy(update={"min_turns": times.turns})  # II-6.2: turns for the accuracy
    g = gates
    basis = {
        "gyro 1-6": f"{times.turns} whole turns at {plan.table_rate_deg_s:g} deg/s: "
        f"{g['gyro 1-6'].why} (Chart II-18)",
        "gyro 7-15": f"{gyro_gate_s / 60:g} min of S1^T ticks: {g['gyro 7-15'].why} "
        "(Chart II-19)" + ("" if gate == "clock" else "; pulse gate (II-5.2): each gyro's "
        "preset is its rate in a short clock-gated probe at the position times this time"),
        "accelerometer 7-15": f"{acc_v_s / 60:g} min vertical ({g['accel vertical'].why}), "
        f"{acc_h_s / 60:g} min horizontal ({g['accel horizontal'].why}) times the {f0:g} Hz "
        "basic frequency (Charts II-21..II-24)",
    }
    presets = st_settings.counter_settings(plan, s1, f0, gyro_gate_s, acc_v_s, acc_h_s, basis)
    presets = presets.model_copy(update={"gates": gates})
    run.save_sheet("counter_settings", presets)
    outputs = CounterOutputs()
    data = DayData(survey=survey, s1=s1, f0=f0)

    def chart(key: str, fn: Callable[[], Any]) -> Any:
        """One measurement chart as a block: its data and its Counter Outputs rows."""
        def measure() -> dict:
            before = dict(outputs.outputs)
            got = fn()
            rows = {k: v for k, v in outputs.outputs.items() if before.get(k) != v}
            return {"data": got, "outputs": rows}

        value = run.block(key, measure, lambda v: v)
        outputs.outputs.update(value["outputs"])
        return chart_data(value)

    if "II-6" in wanted and (pairs := _pairs((1, 3, 5), pos)):
        data.gyro.update(chart("II-6", lambda: scale_factor_positions(
            st, run, settings, plan, outputs, pairs)))
    if "II-7" in wanted:
        data.nonlinearity = chart("II-7", lambda: nonlinearity_experiment(
            st, run, settings, plan, s1, site.omega_sin_lambda))
    if "II-7Q" in wanted:
        data.q_is = chart("II-7Q", lambda: q_is_experiment(
            st, run, survey.t_bi, plan, s1, site.omega_sin_lambda))
    if "II-10" in wanted:
        data.j_term = chart("II-10", lambda: j_experiment(st, run, settings, plan, s1))
    pos12 = pos
    together = plan.options.simultaneous  # II-5: gyros and accelerometers in one setting
    counters = plan.options.counters
    if together and {"II-11", "II-13"} <= wanted and (pairs := _pairs((7, 9, 11), pos)):
        both = chart(sim.CHART_7_12, lambda: sim.positions_7_12(
            st, run, settings, presets, outputs, s1, f0, counters, pairs, unc["A"], prec["A"]))
        data.gyro.update({m: v["gyro"] for m, v in both.items()})
        data.accel.update({m: v["accel"] for m, v in both.items()})
        wanted -= {"II-11", "II-13"}
    if together and {"II-12", "II-14"} <= wanted and (singles := _singles((13, 14), pos)):
        both = chart(sim.CHART_13_14, lambda: sim.positions_13_14(
            st, run, settings, presets, outputs, s1, f0, counters, singles, unc["A"],
            prec["A"]))
        data.gyro.update({m: v["gyro"] for m, v in both.items()})
        data.accel.update({m: v["accel"] for m, v in both.items()})
        wanted -= {"II-14"}
        pos12 = {15} if pos is None else pos & {15}  # II-12 keeps position 15 alone
    if "II-11" in wanted and (pairs := _pairs((7, 9, 11), pos)):
        data.gyro.update(chart("II-11", lambda: gyro_positions_7_12(
            st, run, settings, presets, outputs, s1, pairs, unc["G"], prec["G"], gate)))
    if "II-12" in wanted and (singles := _singles((13, 14, 15), pos12)):
        data.gyro.update(chart("II-12", lambda: gyro_positions_13_15(
            st, run, settings, presets, outputs, s1, singles, unc["G"], prec["G"], gate)))
    if "II-13" in wanted and (pairs := _pairs((7, 9, 11), pos)):
        data.accel.update(chart("II-13", lambda: accel_positions_7_12(
            st, run, settings, presets, outputs, s1, f0, pairs, unc["A"], prec["A"])))
    if "II-14" in wanted and (singles := _singles((13, 14), pos)):
        data.accel.update(chart("II-14", lambda: accel_positions_13_14(
            st, run, settings, presets, outputs, s1, f0, singles, unc["A"], prec["A"])))
    tilts = plan.options.extra_accel_tilts_deg  # beyond the manual: none by default
    if "II-14E" in wanted and tilts and pos is None:
        data.extra_accel = chart("II-14E", lambda: extra_accel_positions(
            st, run, np.asarray(survey.t_bi, dtype=float), tilts, acc_v_s, outputs, f0,
            unc["A"], prec["A"]))
    run.save_sheet("counter_outputs", outputs)
    return data
