"""The full calibration day of report 000, Parts I and II, in the laboratory's order.

Turn-on (I-1), system survey (I-2), resolver and counter settings (II-6), the measurement
check-sheets (II-6, II-7, II-7Q, II-10, II-11, II-12, II-13, II-14) and the calibration
computations (II-15). ``only`` restricts the measurements to some charts (turn-on and survey
always run: everything needs them); the computations then give exactly what Chart II-16
allows from the positions measured.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from procedures import settings as st_settings
from procedures.accel_static import accel_positions_7_12, accel_positions_13_14
from procedures.gyro_rotating import scale_factor_positions
from procedures.gyro_static import gyro_positions_7_12, gyro_positions_13_15
from procedures.j_term import j_experiment
from procedures.nonlinearity import nonlinearity_experiment, q_is_experiment
from procedures.plan import DayPlan
from procedures.positions import resolver_settings
from procedures.runner import Run
from procedures.sheets import CounterOutputs, SurveyResults
from procedures.system_survey import system_survey
from procedures.turn_on import turn_on

EXPERIMENTS = ("II-6", "II-7", "II-7Q", "II-10", "II-11", "II-12", "II-13", "II-14")


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


def measure_day(st, run: Run, plan: DayPlan, site: dict, f0: float,
                only: tuple[str, ...] | None = None) -> DayData:
    """Turn-on, survey, settings and the measurement check-sheets; returns the data."""
    wanted = set(EXPERIMENTS if not only else only)
    unknown = wanted - set(EXPERIMENTS) - {"I-1", "I-2"}
    if unknown:
        raise ValueError(f"unknown chart(s) {sorted(unknown)}; choose from {EXPERIMENTS}")
    turn_on(st, run, plan.warmup_s)
    survey = system_survey(st, run, site)
    s1 = st.oscillator.s_t(1)
    settings = resolver_settings(survey)
    run.save_sheet("resolver_settings", settings)
    run.save_sheet("counter_connections", st_settings.counter_connections())
    gyro_gate_s, acc_v_s, acc_h_s = 600.0, 600.0, 1800.0
    basis = {
        "gyro 1-6": f"{plan.min_turns} whole turns at {plan.table_rate_deg_s:g} deg/s "
        f"(scale factor to {plan.gyro_scale_factor_rel:g} needs one turn, Chart II-18)",
        "gyro 7-15": f"{gyro_gate_s / 60:g} min of S1^T ticks for "
        f"{plan.gyro_drift_deg_hr:g} deg/hr (Chart II-19)",
        "accelerometer 7-15": f"{acc_v_s / 60:g} min vertical, {acc_h_s / 60:g} min horizontal "
        f"times the {f0:g} Hz basic frequency (Charts II-21..II-24)",
    }
    presets = st_settings.counter_settings(plan, s1, f0, gyro_gate_s, acc_v_s, acc_h_s, basis)
    run.save_sheet("counter_settings", presets)
    outputs = CounterOutputs()
    data = DayData(survey=survey, s1=s1, f0=f0)
    if "II-6" in wanted:
        data.gyro.update(scale_factor_positions(st, run, settings, plan, outputs))
    if "II-7" in wanted:
        data.nonlinearity = nonlinearity_experiment(
            st, run, settings, plan, s1, site["omega_sin_lambda"]
        )
    if "II-7Q" in wanted:
        data.q_is = q_is_experiment(st, run, survey.t_bi, plan, s1, site["omega_sin_lambda"])
    if "II-10" in wanted:
        data.j_term = j_experiment(st, run, settings, plan, s1)
    if "II-11" in wanted:
        data.gyro.update(gyro_positions_7_12(st, run, settings, presets, outputs, s1))
    if "II-12" in wanted:
        data.gyro.update(gyro_positions_13_15(st, run, settings, presets, outputs, s1))
    if "II-13" in wanted:
        data.accel.update(accel_positions_7_12(st, run, settings, presets, outputs, s1, f0))
    if "II-14" in wanted:
        data.accel.update(accel_positions_13_14(st, run, settings, presets, outputs, s1, f0))
    run.save_sheet("counter_outputs", outputs)
    return data
