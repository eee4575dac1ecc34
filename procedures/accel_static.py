"""II-3.1 (Chart II-13) and II-3.2 (Chart II-14): accelerometer calibration, positions 7-14.

Each counter measures one string ("measure X-Y", X = string, Z = S1^T): the clock ticks it
takes the string to give the preset number of pulses. Bubble-level corrections always.
"""

from __future__ import annotations

from procedures.common import patch, run_counters, set_modes, set_position
from procedures.runner import Run
from procedures.settings import ACCEL, STRINGS, wiring
from procedures.sheets import CounterOutputs, CounterSettings, ResolverSettings

TITLE_7_12 = "Accelerometer bias, scale factor, second order and (Q^A)^-1, positions 7 to 12"
TITLE_13_14 = "Accelerometer third order terms, positions 13 and 14"
COUNTERS = tuple(STRINGS)


def _measure(st, sheet, settings, presets, outputs, data, mm, first_step, text, s1, f0):
    p = settings.positions[str(mm)]
    tag = f"/m{mm}"
    with sheet.step(first_step + tag, text) as s:
        ps = set_position(st, 0.0, 90.0, p.phi3, p.phi4, level=True)
        s.reading = {"phi1": ps.phi[0], "phi3": ps.phi[2], "phi4": ps.phi[3],
                     "level_arcsec": ps.level_arcsec}
    n = {c: int(presets.presets[f"accel {mm}"][str(c)]) for c in COUNTERS}
    timeout = max(n.values()) / f0 * 1.3 + 60.0
    with sheet.step("7" + tag, "Set the string-count presets on counters 1-6") as s:
        s.reading = {str(c): v for c, v in n.items()}
    with sheet.step("8" + tag, "Switch counters to operate; after the print-outs, standby") as s:
        gate = run_counters(st, n, timeout)
        s.reading = {str(c): v for c, v in gate.readings.items()}
    with sheet.step("9" + tag, "Record the clock counts on the Counter Outputs Sheet") as s:
        outputs.outputs[f"accel {mm}"] = {str(c): v for c, v in gate.readings.items()}
        data[mm] = {
            "gamma": {str(c): n[c] for c in COUNTERS},
            "n1": {str(c): gate.readings[c] for c in COUNTERS},
            "t0": gate.t_oper,
            "t1": gate.t_done,
            "t_level": ps.t_level,
        }
        s.reading = data[mm]


def _setup(st, sheet) -> None:
    sheet.done("1", "Resolver and counter settings available")
    sheet.done("2", "Turn-on procedures complete (Chart I-1)")
    with sheet.step("3", "Patch accelerometer strings and master oscillator to counters 1-6"):
        patch(st, wiring(ACCEL))
    with sheet.step("4", "Set counters 1-6 to measure X-Y"):
        set_modes(st, COUNTERS, "measure X-Y")
    with sheet.step("5", "Set phi1 to 0 deg plus level correction, phi2 to 90 deg") as s:
        ps = set_position(st, 0.0, 90.0, st.table.position(3), st.table.position(4), level=True)
        s.reading = {"level_arcsec": ps.level_arcsec}


def accel_positions_7_12(st, run: Run, settings: ResolverSettings, presets: CounterSettings,
                         outputs: CounterOutputs, s1: float, f0: float, pairs=(7, 9, 11)
                         ) -> dict[int, dict]:
    data: dict[int, dict] = {}
    with run.sheet("II-13", TITLE_7_12) as sheet:
        _setup(st, sheet)
        for m in pairs:
            _measure(st, sheet, settings, presets, outputs, data, m, "6",
                     f"Set phi3, phi4 to position {m} with level correction", s1, f0)
            _measure(st, sheet, settings, presets, outputs, data, m + 1, "10",
                     f"Turn phi3 by 180 deg: position {m + 1} (level re-read)", s1, f0)
    return data


def accel_positions_13_14(st, run: Run, settings: ResolverSettings, presets: CounterSettings,
                          outputs: CounterOutputs, s1: float, f0: float, positions=(13, 14)
                          ) -> dict[int, dict]:
    data: dict[int, dict] = {}
    with run.sheet("II-14", TITLE_13_14) as sheet:
        _setup(st, sheet)
        for m in positions:
            _measure(st, sheet, settings, presets, outputs, data, m, "6",
                     f"Set phi3, phi4 to position {m} with level correction", s1, f0)
    return data
