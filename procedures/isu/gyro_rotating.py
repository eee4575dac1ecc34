"""II-1.1 (Chart II-6): gyro scale factor and (Q^G)^-1, positions 1-6, table turning.

Counter 1 counts clock ticks and counters 2-4 count each gyro's net pulses, all gated by
the same N whole turns of the rotary axis ("measure Z", Z = table rotation pulses).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from procedures.isu.common import (
    check_repeated_counts,
    check_turns_clock,
    patch,
    patch_check_counter,
    rotary_axis_turning,
    run_counters,
    set_modes,
    set_position,
)
from procedures.isu.plan import DayPlan
from procedures.isu.readings import axis_rate, resolver
from procedures.isu.settings import ALONG_AXIS_CHECK, GYRO_ROTATING, turning_repeats, wiring
from procedures.isu.sheets import CounterOutputs, ResolverSettings
from procedures.isu.turn_on import oscillator_periods
from procedures.runner import CheckSheetRun, Run
from station.config.calibration import set_to

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

TITLE = "Gyro scale factor and (Q^G)^-1, positions 1 to 6"


def wait_clear_of_pulse(st: IsuDrivers, rate_deg_s: float, ppr: int, margin_s: float = 1.0) -> None:
    """Step 9: switch on only after the rotary output has just fired, so that no pulse falls
    between the counters being switched (they must all share one gate)."""
    pitch = 360.0 / ppr
    phi2 = resolver(st, 2)
    to_next = (pitch - phi2 % pitch) if rate_deg_s > 0 else (phi2 % pitch or pitch)
    t_next = to_next / abs(rate_deg_s)
    if t_next < margin_s:
        st.clock.sleep(t_next + 0.1)


def position_pair(st: IsuDrivers, sheet: CheckSheetRun, settings: ResolverSettings,
                  plan: DayPlan, m: int, outputs: CounterOutputs, data: dict) -> None:
    """Steps 7-14 for positions m and m + 1; step numbers carry the position (e.g. 9/m2)."""
    n_pulses = plan.min_turns * plan.rotation_pulses_per_rev
    timeout = 2.0 * plan.min_turns * 360.0 / plan.table_rate_deg_s + 60.0
    k_along = (m + 1) // 2  # gyro whose input axis the pair puts along the rotary axis
    repeats = turning_repeats(k_along)
    moving = plan.options.turn_phi3_moving  # Chart II-6 step 13's option
    for first, mm in ((True, m), (False, m + 1)):
        p = settings.positions[str(mm)]
        tag = f"/m{mm}"
        text = (f"Set phi3, phi4 to position {mm}" if first
                else f"Turn phi3 by 180 deg: position {mm}"
                + (" (the table still turning)" if moving else ""))
        with sheet.step(("7" if first else "12") + tag, text) as s:
            prec = plan.options.precision_scale_factor_arcsec  # II-6.1: about 1 deg will do
            set_position(st, 90.0, None, set_to(p.phi3, prec), set_to(p.phi4, prec),
                         level=False)
            if first:  # counter 5 counts the gyro along the axis again
                patch_check_counter(st, ALONG_AXIS_CHECK, k_along)
            s.reading = {"phi3": p.phi3, "phi4": p.phi4}
            if prec > 0:  # what the table was set to (II-6.1's precision option)
                s.reading["set_deg"] = [set_to(p.phi3, prec), set_to(p.phi4, prec)]
        text8 = ("Table still turning at the measurement speed: check it" if moving
                 and not first else "Start the table turning at the measurement speed")
        with sheet.step(("8" if first else "13") + tag, text8) as s:
            if not (moving and not first):
                st.table.rotate(2, plan.table_rate_deg_s)
            st.table.wait_still()
            s.reading = {"rate_deg_s": axis_rate(st, 2, plan.table_rate_deg_s)}
        with sheet.step("9" + tag, "After a rotary output pulse, switch counters 1-4 to "
                        "operate together") as s:
            wait_clear_of_pulse(st, plan.table_rate_deg_s, plan.rotation_pulses_per_rev)
            gate = run_counters(st, {c: n_pulses for c in (1, 2, 3, 4, *repeats)}, timeout,
                                rotary_axis_turning(st, plan.table_rate_deg_s))
            check_repeated_counts(st, gate, repeats, None)
            s1, _ = oscillator_periods(sheet.run)
            check_turns_clock(st, 1, gate.readings[1], n_pulses, s1,
                              360.0 / plan.rotation_pulses_per_rev, plan.table_rate_deg_s)
            s.reading = {str(c): v for c, v in gate.readings.items()}
        keep = moving and first  # turning on into position m + 1
        with sheet.step("10" + tag, "Counters printed: standby"
                        + ("; the table kept turning" if keep else "; stop the table")):
            if not keep:
                st.table.stop(2)
                st.table.wait_still()
        with sheet.step("11" + tag, "Record the outputs on the Counter Outputs Sheet") as s:
            outputs.outputs[f"gyro {mm}"] = {str(c): v for c, v in gate.readings.items()}
            data[mm] = {
                "n1": gate.readings[1],
                "n_phi": n_pulses,
                "delta": tuple(gate.readings[c] for c in (2, 3, 4)),
                "t0": gate.t_oper,
                "t1": gate.t_done,
            }
            s.reading = data[mm]


def scale_factor_positions(st: IsuDrivers, run: Run, settings: ResolverSettings,
                           plan: DayPlan, outputs: CounterOutputs,
                           positions: tuple[int, ...] = (1, 3, 5)) -> dict[int, dict]:
    """Positions 1-6 (pairs m, m + 1 for m in ``positions``); returns the gyro data by position."""
    data: dict[int, dict] = {}
    with run.sheet("II-6", TITLE) as sheet:
        sheet.done("1", "Resolver and counter settings available", {"positions": list(range(1, 7))})
        sheet.done("2", "Turn-on procedures complete (Chart I-1)")
        with sheet.step("3", "Patch gyros, master oscillator and rotary output to counters 1-4 "
                        "(and again to 5, 6)"):
            patch(st, wiring(GYRO_ROTATING))
        with sheet.step("4", "Set counters 1-4 to measure Z (and 5, 6 counting again)"):
            set_modes(st, (1, 2, 3, 4, 5, 6), "measure Z")
        with sheet.step("5", "Set phi1 to 90 deg (rotary axis horizontal)"):
            st.table.move(1, 90.0)
            st.table.set_pulses_per_rev(plan.rotation_pulses_per_rev)
            st.table.wait_still()
        with sheet.step("6", "Set the turn count on counters 1-4") as s:
            s.reading = {"preset": plan.min_turns * plan.rotation_pulses_per_rev}
        for m in positions:
            position_pair(st, sheet, settings, plan, m, outputs, data)
    return data
