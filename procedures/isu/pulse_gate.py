"""II-5.2's alternative gyro gate for the static positions 7-15 (Charts II-11, II-12).

The manual counts each gyro's pulses over a preset of clock ticks; II-5.2 notes that timing
a preset number of gyro pulses (counter in "measure X-Y" on the gyro's +/- lines, the clock
on Z) quantizes less, but that the number is hard to fix beforehand without knowing the
constants. Here it is fixed at each position: a short clock-gated probe gives each gyro's
sign and rate, and the preset is that rate times the planned gate (Counter Settings Sheet,
II-6.2), so each gate lasts about the planned time. A gyro whose probe count is too small
(rate near zero: its gate might never close, or its sign is unsure) is counted over the
clock gate as the manual does, and the step says so naming the gyro and position.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from procedures.isu.common import Gate, run_counters, set_modes
from procedures.isu.plausibility import Implausible, source_of

if TYPE_CHECKING:
    from procedures.runner import CheckSheetRun
    from station.drivers.isu import IsuDrivers

PROBE_FRACTION = 0.05  # the probe's share of the planned gate
PROBE_MIN_S = 20.0  # and at least this long
PROBE_MIN_COUNT = 8  # |probe count| below this: the rate is too near zero for a pulse gate
TIMEOUT_FACTOR = 3.0  # a pulse gate may last this many planned gates before it is refused
MAIN = {2: 1, 3: 2, 4: 3}  # counter -> gyro (Chart II-2, positions 7-15)


@dataclass(frozen=True)
class PulseChoice:
    """Gyro k's gate at one position: ``preset`` pulses in ``sign``'s direction, or (not
    ``pulse``) the clock gate, with ``why``."""

    k: int
    pulse: bool
    preset: int
    sign: int
    probe_count: int
    why: str


def choose(k: int, m: int, probe_count: int, probe_s: float, gate_s: float) -> PulseChoice:
    """Gyro k's gate at position m from its probe (``probe_count`` net pulses over
    ``probe_s``): a preset of its rate times the planned ``gate_s``, or the clock gate when
    the rate is too near zero."""
    if abs(probe_count) < PROBE_MIN_COUNT:
        return PulseChoice(k, False, 0, 0, probe_count,
                           f"gyro {k} in position {m}: {probe_count} pulses in the {probe_s:g} s "
                           f"probe (fewer than {PROBE_MIN_COUNT}): rate too near zero for a pulse "
                           "gate, counted over the clock gate")
    n = max(int(round(abs(probe_count) * gate_s / probe_s)), 1)
    sign = 1 if probe_count > 0 else -1
    return PulseChoice(k, True, n, sign, probe_count,
                       f"gyro {k} in position {m}: {n} pulses ({probe_count:+d} in the "
                       f"{probe_s:g} s probe)")


def probe_ticks(clock_ticks: int, s1: float) -> int:
    """The probe's clock preset from the planned gate's (``s1``: s per tick)."""
    return max(int(round(PROBE_FRACTION * clock_ticks)), int(round(PROBE_MIN_S / s1)))


def check_repeats(st: IsuDrivers, gate: Gate, repeats: dict[int, int],
                  choices: dict[int, PulseChoice], s1: float, clock_ticks: int) -> None:
    """A check counter over the same gyro as its main counter must agree: clock-gated,
    within 2 pulses plus those of the switch interval; pulse-gated (clock ticks), within 2
    ticks plus one pulse period for each pulse the switch interval may hold."""
    for c, main in repeats.items():
        if c not in gate.readings or main not in gate.readings:
            continue
        a, b = gate.readings[main], gate.readings[c]
        ch = choices[MAIN[main]]
        dt = abs(gate.t_each[c] - gate.t_each[main])
        if ch.pulse:
            per_pulse = max(a, b) / ch.preset  # clock ticks per pulse
            allowed = 2.0 + per_pulse * (1.0 + ch.preset * dt / (max(a, b) * s1))
        else:
            rate = max(abs(a), abs(b)) / (clock_ticks * s1)
            allowed = 2.0 + rate * dt
        if abs(a - b) > allowed:
            raise Implausible(
                f"{source_of(st.counters[main])} and {source_of(st.counters[c])}",
                f"counted the same gyro over the same gate as {a} and {b} (allowed "
                f"difference {allowed:.3g}): one reading is garbled")


def measure(st: IsuDrivers, sheet: CheckSheetRun, m: int, tag: str, clock: dict[int, int],
            repeats: dict[int, int], s1: float) -> tuple[Gate, dict]:
    """Steps 7-8 of Charts II-11, II-12 with the pulse gate: the probe, the presets, the
    gates; returns the gate and the position's record (GyroPosition's fields)."""
    n_clock = clock[2]
    gate_s = n_clock * s1
    probe = probe_ticks(n_clock, s1)
    with sheet.step("7a" + tag, f"Probe: count gyros 1-3 over {probe * s1:g} s of clock "
                    "ticks (sign and rate for the pulse presets, II-5.2)") as s:
        set_modes(st, (*MAIN, *repeats), "measure Z")
        pg = run_counters(st, {c: probe for c in MAIN}, probe * s1 * 1.5 + 60.0)
        choices = {k: choose(k, m, pg.readings[c], probe * s1, gate_s) for c, k in MAIN.items()}
        s.reading = {"probe_ticks": probe, **{str(c): v for c, v in pg.readings.items()},
                     "choices": [ch.why for ch in choices.values()]}
    presets: dict[int, int] = {}
    for c in (*MAIN, *repeats):
        ch = choices[MAIN[repeats.get(c, c)]]
        presets[c] = ch.preset if ch.pulse else n_clock
    with sheet.step("7" + tag, "Set each gyro's pulse preset (measure X-Y), or the clock "
                    "preset for a gyro too near zero rate") as s:
        for c in presets:
            pulse = choices[MAIN[repeats.get(c, c)]].pulse
            st.counters[c].set_mode("measure X-Y" if pulse else "measure Z")
        s.reading = {str(c): v for c, v in presets.items()}
    with sheet.step("8" + tag, "Switch counters to operate; after the print-out, standby") as s:
        gate = run_counters(st, presets, TIMEOUT_FACTOR * gate_s + 60.0)
        check_repeats(st, gate, repeats, choices, s1, n_clock)
        s.reading = {str(c): v for c, v in gate.readings.items()}
    delta, n1 = [], []
    for c, k in MAIN.items():
        ch = choices[k]
        delta.append(ch.sign * ch.preset if ch.pulse else gate.readings[c])
        n1.append(gate.readings[c] if ch.pulse else n_clock)
    record = {"n1": n_clock, "delta": tuple(delta), "t0": gate.t_oper, "t1": gate.t_done,
              "n1_each": tuple(n1), "pulse_gated": tuple(choices[k].pulse for k in (1, 2, 3))}
    return gate, record
