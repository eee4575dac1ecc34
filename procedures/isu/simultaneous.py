"""II-5's remark made a procedure: gyro and accelerometer positions 7-14 in one setting.

Report 000 measures the gyros (Charts II-11, II-12) and the accelerometers (II-13, II-14) in
series over the same table positions only because six counters cannot take both; with nine
(or twelve) the strings go to counters 1-6 ("measure X-Y", as II-13) and the gyros to 7-9
("measure Z" over the clock, as II-11; 10-12 count them again), all switched to operate at
once after each setting: the gyro gate runs inside the accelerometers' (config
``[calibration] simultaneous``, ``counters``). Position 15 has no accelerometer reading: it
stays on Chart II-12.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from procedures.isu.common import Gate, PositionSet, check_repeated_counts, run_counters, set_modes
from procedures.isu.settings import SIMULTANEOUS, STRINGS
from procedures.isu.sheets import CounterOutputs, CounterSettings, ResolverSettings
from procedures.isu.static_positions import (
    StaticKind,
    Uncorrected,
    pair_steps,
    run_static,
    single_steps,
)
from procedures.runner import CheckSheetRun, Run

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

CHART_7_12 = "II-11+II-13"
CHART_13_14 = "II-12+II-14"
TITLE_7_12 = "Gyro and accelerometer positions 7 to 12, measured together (II-5)"
TITLE_13_14 = "Gyro and accelerometer positions 13 and 14, measured together (II-5)"
ACCEL_COUNTERS = tuple(STRINGS)
GYRO_COUNTERS = {7: 1, 8: 2, 9: 3}  # counter -> gyro


def gyro_repeats(counters: int) -> dict[int, int]:
    """Check counter -> the gyro counter it repeats (with 12 counters)."""
    return {c + 3: c for c in GYRO_COUNTERS} if counters >= 12 else {}


def _kind(presets: CounterSettings, s1: float, f0: float, counters: int) -> StaticKind:
    repeats = gyro_repeats(counters)

    def measure(st: IsuDrivers, sheet: CheckSheetRun, m: int, tag: str, n: dict[int, int],
                ps: PositionSet) -> tuple[Gate, dict]:
        n_gyro = int(presets.presets[f"gyro {m}"]["2"])
        gyros = {c: n_gyro for c in (*GYRO_COUNTERS, *repeats)}
        with sheet.step("7" + tag, "Set the string-count presets on counters 1-6 and the "
                        f"clock-count presets on counters {min(gyros)}-{max(gyros)}") as s:
            set_modes(st, gyros, "measure Z")
            s.reading = {str(c): v for c, v in {**n, **gyros}.items()}
        with sheet.step("8" + tag, "Switch counters to operate; after the print-outs, "
                        "standby") as s:
            timeout = max(max(n.values()) / f0 * 1.3, n_gyro * s1 * 1.5) + 60.0
            gate = run_counters(st, {**n, **gyros}, timeout)
            check_repeated_counts(st, gate, repeats, n_gyro * s1)
            s.reading = {str(c): v for c, v in gate.readings.items()}
        # the gyro gate opens at its counter's switch to operate (the next clock tick)
        t0 = gate.t_each[7]
        gyro = {"n1": n_gyro, "delta": tuple(gate.readings[c] for c in GYRO_COUNTERS),
                "t0": t0, "t1": t0 + (n_gyro + 1) * s1}
        accel = {"gamma": {str(c): n[c] for c in ACCEL_COUNTERS},
                 "n1": {str(c): gate.readings[c] for c in ACCEL_COUNTERS},
                 "t0": gate.t_oper, "t1": gate.t_done, "t_level": ps.t_level}
        rows = {f"accel {m}": {str(c): gate.readings[c] for c in ACCEL_COUNTERS},
                f"gyro {m}": {str(c): gate.readings[c] for c in gyros}}
        return gate, {"gyro": gyro, "accel": accel, "outputs": rows}

    return StaticKind(
        experiment=SIMULTANEOUS, counters=ACCEL_COUNTERS, mode="measure X-Y",
        sheet_key="accel",
        patch_text="Patch accelerometer strings to counters 1-6, gyros to counters "
        f"7-{max(GYRO_COUNTERS) + len(repeats)}, master oscillator to every Z",
        preset_text="", operate_text="",
        record_text="Record the clock and gyro counts on the Counter Outputs Sheet",
        timeout=lambda n: 0.0, record=lambda n, gate, ps: {}, measure=measure,
        n_counters=counters,
    )


def positions_7_12(st: IsuDrivers, run: Run, settings: ResolverSettings,
                   presets: CounterSettings, outputs: CounterOutputs, s1: float, f0: float,
                   counters: int, pairs: tuple[int, ...] = (7, 9, 11),
                   uncorrected: Uncorrected | None = None, precision_arcsec: float = 0.0
                   ) -> dict[int, dict]:
    """Charts II-11 and II-13 together: position -> {"gyro": ..., "accel": ...}."""
    return run_static(st, run, CHART_7_12, TITLE_7_12, _kind(presets, s1, f0, counters),
                      settings, presets, outputs, pair_steps(pairs), uncorrected,
                      precision_arcsec)


def positions_13_14(st: IsuDrivers, run: Run, settings: ResolverSettings,
                    presets: CounterSettings, outputs: CounterOutputs, s1: float, f0: float,
                    counters: int, positions: tuple[int, ...] = (13, 14),
                    uncorrected: Uncorrected | None = None, precision_arcsec: float = 0.0
                    ) -> dict[int, dict]:
    """Charts II-12 (13, 14) and II-14 together."""
    return run_static(st, run, CHART_13_14, TITLE_13_14, _kind(presets, s1, f0, counters),
                      settings, presets, outputs, single_steps(positions), uncorrected,
                      precision_arcsec)
