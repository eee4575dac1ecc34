"""II-3.1 (Chart II-13) and II-3.2 (Chart II-14): accelerometer calibration, positions 7-14.

Each counter measures one string ("measure X-Y", X = string, Z = S1^T): the clock ticks it
takes the string to give the preset number of pulses. Bubble-level corrections always.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from procedures.isu.common import Gate, PositionSet
from procedures.isu.settings import ACCEL, STRINGS
from procedures.isu.sheets import CounterOutputs, CounterSettings, ResolverSettings
from procedures.isu.static_positions import (
    StaticKind,
    Uncorrected,
    pair_steps,
    run_static,
    single_steps,
)
from procedures.runner import Run

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

TITLE_7_12 = "Accelerometer bias, scale factor, second order and (Q^A)^-1, positions 7 to 12"
TITLE_13_14 = "Accelerometer third order terms, positions 13 and 14"
COUNTERS = tuple(STRINGS)


def accel_kind(f0: float) -> StaticKind:
    """What an accelerometer position counts and records (Charts II-13, II-14)."""

    def record(n: dict[int, int], gate: Gate, ps: PositionSet) -> dict:
        return {"gamma": {str(c): n[c] for c in COUNTERS},
                "n1": {str(c): gate.readings[c] for c in COUNTERS},
                "t0": gate.t_oper, "t1": gate.t_done, "t_level": ps.t_level}

    return StaticKind(
        experiment=ACCEL, counters=COUNTERS, mode="measure X-Y", sheet_key="accel",
        patch_text="Patch accelerometer strings and master oscillator to counters 1-6",
        preset_text="Set the string-count presets on counters 1-6",
        operate_text="Switch counters to operate; after the print-outs, standby",
        record_text="Record the clock counts on the Counter Outputs Sheet",
        timeout=lambda n: max(n.values()) / f0 * 1.3 + 60.0, record=record,
    )


def accel_positions_7_12(st: IsuDrivers, run: Run, settings: ResolverSettings,
                         presets: CounterSettings, outputs: CounterOutputs, s1: float,
                         f0: float, pairs: tuple[int, ...] = (7, 9, 11),
                         uncorrected: Uncorrected | None = None,
                        precision_arcsec: float = 0.0) -> dict[int, dict]:
    return run_static(st, run, "II-13", TITLE_7_12, accel_kind(f0), settings, presets, outputs,
                      pair_steps(pairs), uncorrected, precision_arcsec)


def accel_positions_13_14(st: IsuDrivers, run: Run, settings: ResolverSettings,
                          presets: CounterSettings, outputs: CounterOutputs, s1: float,
                          f0: float, positions: tuple[int, ...] = (13, 14),
                          uncorrected: Uncorrected | None = None,
                        precision_arcsec: float = 0.0) -> dict[int, dict]:
    return run_static(st, run, "II-14", TITLE_13_14, accel_kind(f0), settings, presets, outputs,
                      single_steps(positions), uncorrected, precision_arcsec)
