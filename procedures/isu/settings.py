"""II-6: counter connections (Chart II-2) and counter settings from required accuracies.

The report fixes each preset by (1) a required accuracy, (2) the data-collection time that
reaches it (Charts II-18..II-24), (3) that time in counts. Step (2) here is
``collection_times``: the predicted sigma against time of the lab's covariance model
(procedures.isu.accuracy) gives, per gate, the smallest time meeting the plan's
requirement, never below the manual's standard duration (10 turns; 10 min gyro; 10 min
vertical / 30 min horizontal accelerometer, II-6.2), and refuses (naming the requirement)
what no gate up to the plan's maximum reaches. The Counter Settings Sheet records, per
gate, the requirement, the predicted sigma at the chosen time and why.
"""

from __future__ import annotations

import math
from dataclasses import replace

from procedures.isu.accuracy import (
    SQUARE,
    GateChoice,
    Lab,
    Matrix3,
    Times,
    choose_times,
    planning_mounting,
)
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.plan import DayPlan
from procedures.isu.sheets import (
    CounterConnection,
    CounterConnections,
    CounterSettings,
    GateSetting,
)
from procedures.isu.site import Site

GYRO_ROTATING = "gyro 1-6"
GYRO_STATIC = "gyro 7-15"
ACCEL = "accelerometer 7-15"
SIMULTANEOUS = "gyro and accelerometer 7-14"  # II-5: with nine or twelve counters

STRINGS = {1: "A1S1", 2: "A1S2", 3: "A2S1", 4: "A2S2", 5: "A3S1", 6: "A3S2"}
# Positions 7-15 leave counters 5, 6 and 1 free: each counts a gyro again over the same
# clock gate (the panel lets a line feed several inputs), so every gyro count is read twice
# (project addition to Chart II-2: a count has no other repetition, procedures.isu.plausibility)
GYRO_CHECK_COUNTERS = {5: 2, 6: 3, 1: 4}  # check counter -> counter it repeats
# Positions 1-6 and the speed series leave counters 5 and 6 free: 5 counts again the gyro
# whose input axis is along the rotary axis (re-patched per position pair or gyro), 6 the
# clock, over the same rotation pulses
TURNING_CHECK_COUNTERS = {6: 1}  # and 5 -> the counter of the gyro along the rotary axis
ALONG_AXIS_CHECK = 5


def turning_repeats(k: int) -> dict[int, int]:
    """Check counter -> counter it repeats while gyro k's input axis is along the rotary
    axis (counter k + 1 counts gyro k)."""
    return {ALONG_AXIS_CHECK: k + 1, **TURNING_CHECK_COUNTERS}


def counter_connections() -> CounterConnections:
    """Chart II-2, as patched by the procedures."""
    g = {
        "1": CounterConnection(xy="OSC1", z="TROT", mode="measure Z"),
        **{str(k + 1): CounterConnection(xy=f"G{k}+/G{k}-", z="TROT", mode="measure Z")
           for k in (1, 2, 3)},
        # counter 5: gyro 1 to begin with, then the gyro along the rotary axis
        str(ALONG_AXIS_CHECK): CounterConnection(xy="G1+/G1-", z="TROT", mode="measure Z"),
        "6": CounterConnection(xy="OSC1", z="TROT", mode="measure Z"),
    }
    s = {str(k + 1): CounterConnection(xy=f"G{k}+/G{k}-", z="OSC1", mode="measure Z")
         for k in (1, 2, 3)}
    s |= {str(c): s[str(main)] for c, main in GYRO_CHECK_COUNTERS.items()}
    a = {str(c): CounterConnection(xy=line, z="OSC1", mode="measure X-Y")
         for c, line in STRINGS.items()}
    return CounterConnections(experiments={GYRO_ROTATING: g, GYRO_STATIC: s, ACCEL: a})


def simultaneous_connections(counters: int) -> dict[str, CounterConnection]:
    """II-5's remark: gyro and accelerometer positions 7-14 in one setting. Counters 1-6 the
    accelerometer strings as Chart II-2, 7-9 gyros 1-3 over the clock, and (with 12
    counters) 10-12 the same gyros again, the count read twice as counters 5, 6, 1 do."""
    out = {str(c): CounterConnection(xy=line, z="OSC1", mode="measure X-Y")
           for c, line in STRINGS.items()}
    for k in (1, 2, 3):
        for c in (6 + k, 9 + k) if counters >= 12 else (6 + k,):
            out[str(c)] = CounterConnection(xy=f"G{k}+/G{k}-", z="OSC1", mode="measure Z")
    return out


def wiring(experiment: str, counters: int = 6) -> dict[int, tuple[str | None, str | None, str]]:
    """Patch-panel wiring of an experiment: counter -> (X, Y, Z)."""
    out: dict[int, tuple[str | None, str | None, str]] = {}
    conns = (simultaneous_connections(counters) if experiment == SIMULTANEOUS
             else counter_connections().experiments[experiment])
    for c, conn in conns.items():
        x, _, y = conn.xy.partition("/")
        out[int(c)] = (x, y or None, conn.z)
    return out


def vertical_accelerometer(m: int) -> int | None:
    """Accelerometer along the vertical in position m (7-12), else None."""
    return {7: 1, 8: 1, 9: 2, 10: 2, 11: 3, 12: 3}.get(m)


def counter_settings(
    plan: DayPlan, s1: float, f0: float, gyro_gate_s: float, accel_vertical_s: float,
    accel_horizontal_s: float, basis: dict[str, str],
) -> CounterSettings:
    """Chart II-20: presets for every position and counter."""
    presets: dict[str, dict[str, int]] = {}
    turns = plan.min_turns * plan.rotation_pulses_per_rev
    for m in range(1, 7):
        presets[f"gyro {m}"] = {str(c): turns for c in (1, 2, 3, 4, 5, 6)}
    n_gyro = int(round(gyro_gate_s / s1))
    for m in range(7, 16):
        presets[f"gyro {m}"] = {str(c): n_gyro for c in (2, 3, 4, *GYRO_CHECK_COUNTERS)}
    for m in range(7, 15):
        vert = vertical_accelerometer(m)
        row = {}
        for c in STRINGS:
            k = (c + 1) // 2
            t = accel_vertical_s if vert == k else accel_horizontal_s
            # the basic frequency converts time to counts; II-6.2 prints 10 min x 20,000/s as
            # 1.2 x 10^6 counts, a slip: 600 s x 20,000/s = 1.2 x 10^7
            row[str(c)] = int(math.ceil(t * f0))
        presets[f"accel {m}"] = row
    return CounterSettings(presets=presets, basis=basis)


def planning_lab(plan: DayPlan, site: Site, noise: NoiseSpec, s1: float = 1e-6,
                 f0: float = 20000.0, t_bi: object | None = None) -> Lab:
    """What the accuracy prediction is told of this station and day (``t_bi``: the unit's
    mounting T^BI, the survey's on the day; None: bolted square)."""
    return Lab(site=site, noise=noise, s1=s1, f0=f0, table_rate_deg_s=plan.table_rate_deg_s,
               pulses_per_rev=plan.rotation_pulses_per_rev, t_bi=planning_mounting(t_bi))


def manual_times(plan: DayPlan) -> Times:
    """The manual's standard durations (II-6.2), the operator's whole turns among them."""
    return Times(turns=plan.min_turns)


# The latest answer (one station at a time): its key without the mounting, the planning
# mounting it was made for, and the answer.
_CHOSEN: list[tuple[str, Matrix3, tuple[Times, list[GateChoice]]]] = []
# How far apart two planning mountings may be and still share one answer (rad, each
# element): the prediction needs the mounting only to a fraction of a degree (accuracy.Lab:
# through the sense of its small bolting error), and the survey's differs from the station's
# by its measurement error, which can round across planning_mounting's 1e-4 on either side.
SHARED_MOUNTING = 1e-3


def _shared(key: str, t_bi: Matrix3) -> tuple[Times, list[GateChoice]] | None:
    """The latest answer, if it was asked with the same key on a mounting within
    SHARED_MOUNTING of ``t_bi``."""
    if _CHOSEN and _CHOSEN[0][0] == key:
        held = _CHOSEN[0][1]
        if all(abs(a - b) <= SHARED_MOUNTING for ra, rb in zip(held, t_bi, strict=True)
               for a, b in zip(ra, rb, strict=True)):
            return _CHOSEN[0][2]
    return None


def collection_times(plan: DayPlan, site: Site, noise: NoiseSpec, s1: float = 1e-6,
                     f0: float = 20000.0, t_bi: object | None = None
                     ) -> tuple[Times, dict[str, GateSetting]]:
    """II-6.2 step (2): every gate's time from the plan's required accuracies
    (procedures.isu.accuracy.Unreachable, naming the requirement, when none reaches it);
    ``t_bi``: the unit's mounting (the day's survey), which sets each instrument's share of
    the table's orientation errors."""
    req = plan.requirements
    # planning figures: the counter clock's period to 4 figures, and the mounting to within
    # SHARED_MOUNTING, so that the check before the run (nominal clock, the station's
    # mounting) and II-6 (the measured clock, the survey's) share one answer (issue 17: a
    # second prediction cost 12 ms)
    lab = planning_lab(plan, site, noise, float(f"{s1:.4g}"), f0, t_bi)
    fixed = plan.study_times()
    key = repr((req, replace(lab, t_bi=SQUARE), manual_times(plan), fixed))
    answer = _shared(key, lab.t_bi)
    if answer is None:
        answer = choose_times(req.requirements(), 60.0 * req.max_gate_minutes, lab,
                              manual_times(plan), fixed=fixed)
        _CHOSEN[:] = [(key, lab.t_bi, answer)]
    times, choices = answer
    gates = {c.gate: GateSetting(requirement=c.requirement, required=c.required,
                                 predicted=c.predicted, units=c.units, default=c.default,
                                 chosen=c.chosen, why=c.why) for c in choices}
    return times, gates
