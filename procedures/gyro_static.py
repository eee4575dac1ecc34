"""II-2.1 (Chart II-11) and II-2.2 (Chart II-12): gyro acceleration-sensitive terms.

Counters 2-4 count each gyro's net pulses over a preset number of master-oscillator ticks
("measure Z", Z = S1^T) with the rotary axis up, in positions 7-12 (each body axis up and
down) and 13-15 (bisectors up). Bubble-level corrections are applied in every position
(II-6.1 recommends the habit).
"""

from __future__ import annotations

from procedures.common import patch, run_counters, set_modes, set_position
from procedures.runner import Run
from procedures.settings import GYRO_STATIC, wiring
from procedures.sheets import CounterOutputs, CounterSettings, ResolverSettings

TITLE_7_12 = "Gyro bias, unbalance and square compliance, positions 7 to 12"
TITLE_13_15 = "Gyro product compliance, positions 13 to 15"


def _measure(st, sheet, settings, presets, outputs, data, mm, first_step: str, level_text: str,
             s1: float):
    p = settings.positions[str(mm)]
    tag = f"/m{mm}"
    with sheet.step(first_step + tag, level_text) as s:
        ps = set_position(st, 0.0, 90.0, p.phi3, p.phi4, level=True)
        s.reading = {"phi1": ps.phi[0], "phi3": ps.phi[2], "phi4": ps.phi[3],
                     "level_arcsec": ps.level_arcsec}
    n = {c: int(presets.presets[f"gyro {mm}"][str(c)]) for c in (2, 3, 4)}
    timeout = max(n.values()) * s1 * 1.5 + 60.0
    with sheet.step("7" + tag, "Set the clock-count presets on counters 2-4") as s:
        s.reading = {str(c): v for c, v in n.items()}
    with sheet.step("8" + tag, "Switch counters to operate; after the print-out, standby") as s:
        gate = run_counters(st, n, timeout)
        s.reading = {str(c): v for c, v in gate.readings.items()}
    with sheet.step("9" + tag, "Record the gyro counts on the Counter Outputs Sheet") as s:
        outputs.outputs[f"gyro {mm}"] = {str(c): v for c, v in gate.readings.items()}
        data[mm] = {
            "n1": n[2],
            "delta": tuple(gate.readings[c] for c in (2, 3, 4)),
            "t0": gate.t_oper,
            "t1": gate.t_done,
        }
        s.reading = data[mm]


def _setup(st, sheet) -> None:
    sheet.done("1", "Resolver and counter settings available")
    sheet.done("2", "Turn-on procedures complete (Chart I-1)")
    with sheet.step("3", "Patch gyros and master oscillator to counters 2-4"):
        patch(st, wiring(GYRO_STATIC))
    with sheet.step("4", "Set counters 2-4 to measure Z"):
        set_modes(st, (2, 3, 4), "measure Z")
    with sheet.step("5", "Set phi1 to 0 deg plus level correction, phi2 to 90 deg") as s:
        ps = set_position(st, 0.0, 90.0, st.table.position(3), st.table.position(4), level=True)
        s.reading = {"level_arcsec": ps.level_arcsec}


def gyro_positions_7_12(st, run: Run, settings: ResolverSettings, presets: CounterSettings,
                        outputs: CounterOutputs, s1: float, pairs=(7, 9, 11)) -> dict[int, dict]:
    data: dict[int, dict] = {}
    with run.sheet("II-11", TITLE_7_12) as sheet:
        _setup(st, sheet)
        for m in pairs:
            _measure(st, sheet, settings, presets, outputs, data, m, "6",
                     f"Set phi3, phi4 to position {m} with level correction", s1)
            _measure(st, sheet, settings, presets, outputs, data, m + 1, "10",
                     f"Turn phi3 by 180 deg: position {m + 1} (level re-read)", s1)
    return data


def gyro_positions_13_15(st, run: Run, settings: ResolverSettings, presets: CounterSettings,
                         outputs: CounterOutputs, s1: float, positions=(13, 14, 15)
                         ) -> dict[int, dict]:
    data: dict[int, dict] = {}
    with run.sheet("II-12", TITLE_13_15) as sheet:
        _setup(st, sheet)
        for m in positions:
            _measure(st, sheet, settings, presets, outputs, data, m, "6",
                     f"Set phi3, phi4 to position {m} with level correction", s1)
    return data
