"""II-2.1 (Chart II-11) and II-2.2 (Chart II-12): gyro acceleration-sensitive terms.

Counters 2-4 count each gyro's net pulses over a preset number of master-oscillator ticks
("measure Z", Z = S1^T) with the rotary axis up, in positions 7-12 (each body axis up and
down) and 13-15 (bisectors up). Bubble-level corrections are applied in every position
(II-6.1 recommends the habit). ``gate`` "pulses": II-5.2's alternative, each counter timing
a preset number of its gyro's pulses (procedures.isu.pulse_gate).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from procedures.isu import pulse_gate
from procedures.isu.common import Gate, PositionSet
from procedures.isu.settings import GYRO_CHECK_COUNTERS, GYRO_STATIC
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

TITLE_7_12 = "Gyro bias, unbalance and square compliance, positions 7 to 12"
TITLE_13_15 = "Gyro product compliance, positions 13 to 15"


def _kind(s1: float, gate: str = "clock") -> StaticKind:
    def record(n: dict[int, int], gate: Gate, ps: PositionSet) -> dict:
        return {"n1": n[2], "delta": tuple(gate.readings[c] for c in (2, 3, 4)),
                "t0": gate.t_oper, "t1": gate.t_done}

    return StaticKind(
        experiment=GYRO_STATIC, counters=(2, 3, 4), mode="measure Z", sheet_key="gyro",
        patch_text="Patch gyros and master oscillator to counters 2-4 (and again to 5, 6, 1)",
        preset_text="Set the clock-count presets on counters 2-4",
        operate_text="Switch counters to operate; after the print-out, standby",
        record_text="Record the gyro counts on the Counter Outputs Sheet",
        timeout=lambda n: max(n.values()) * s1 * 1.5 + 60.0, record=record,
        repeats=GYRO_CHECK_COUNTERS, gate_s=lambda n: max(n.values()) * s1,
        measure=None if gate == "clock" else (
            lambda st, sheet, m, tag, n, ps: pulse_gate.measure(
                st, sheet, m, tag, n, GYRO_CHECK_COUNTERS, s1)),
    )


def gyro_positions_7_12(st: IsuDrivers, run: Run, settings: ResolverSettings,
                        presets: CounterSettings, outputs: CounterOutputs, s1: float,
                        pairs: tuple[int, ...] = (7, 9, 11),
                        uncorrected: Uncorrected | None = None,
                        precision_arcsec: float = 0.0, gate: str = "clock") -> dict[int, dict]:
    return run_static(st, run, "II-11", TITLE_7_12, _kind(s1, gate), settings, presets, outputs,
                      pair_steps(pairs), uncorrected, precision_arcsec)


def gyro_positions_13_15(st: IsuDrivers, run: Run, settings: ResolverSettings,
                         presets: CounterSettings, outputs: CounterOutputs, s1: float,
                         positions: tuple[int, ...] = (13, 14, 15),
                         uncorrected: Uncorrected | None = None,
                         precision_arcsec: float = 0.0, gate: str = "clock") -> dict[int, dict]:
    return run_static(st, run, "II-12", TITLE_13_15, _kind(s1, gate), settings, presets, outputs,
                      single_steps(positions), uncorrected, precision_arcsec)
