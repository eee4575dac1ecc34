"""Operations every calibration check-sheet repeats: set a position, patch, run counters.

Each one checks what it reads (``procedures.isu.plausibility``, ``procedures.isu.readings``): the
levelling is confirmed by a second level reading after the table moved; a count read twice
(an idle counter over the same gate) must agree; a counter that times out on a gate the
table's rotation closes asks the table whether its axis turns, so a stalled axis is reported
as the table's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from procedures.isu.calibration.noise_spec import ARCSEC, NoiseSpec
from procedures.isu.plausibility import K_READING, MAX_REREADS, PARSE_ERRORS, Implausible, source_of
from procedures.isu.readings import RATE_TOLERANCE, read_levels, resolver
from station.errors import DriverError

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

ARCSEC_PER_DEG = 3600.0
SPEC = NoiseSpec.model_validate({})  # the lab's specification unless a procedure has its own


@dataclass
class PositionSet:
    """A table setting as commanded, with the bubble-level corrections applied (deg).

    ``level_check_arcsec``: the reading that confirmed the levelling (level 1 near 0, level 2
    unchanged: phi3 turns the ISU, not the platform the levels stand on); ``relevelled``: the
    further corrections a disagreeing confirmation called for.
    """

    phi: tuple[float, float, float, float]
    level_arcsec: tuple[float, float] | None
    t_level: float | None
    level_check_arcsec: tuple[float, float] | None = None
    relevelled: list[dict] = field(default_factory=list)

    def reading(self) -> dict:
        """What a step records of the levelling (the further corrections only if any)."""
        out: dict = {"level_arcsec": self.level_arcsec,
                     "level_check_arcsec": self.level_check_arcsec}
        if self.relevelled:
            out["relevelled"] = self.relevelled
        return out


def level_check_sigma_arcsec(noise: NoiseSpec, dt: float) -> float:
    """Scatter of a confirming level reading about its expected value: two readings, two
    table settings (the move and the correction) and the pier's tilt change over ``dt``."""
    ee0, nn0, _ = noise.tilt_covariance(0.0)
    ee, nn, _ = noise.tilt_covariance(dt)
    tilt = 2.0 * max(float(ee0 - ee), float(nn0 - nn)) / ARCSEC**2
    return math.sqrt(2.0 * (noise.bubble_sigma / ARCSEC) ** 2
                     + 2.0 * noise.table_setting_arcsec**2 + max(tilt, 0.0))


def level_check_z(check: tuple[float, float], applied: tuple[float, float],
                  sigma: float) -> float:
    """Largest deviation (in sigma) of a confirming level reading from what the correction
    leaves: level 1 nulled, level 2 unchanged."""
    return max(abs(check[0]), abs(check[1] - applied[1])) / sigma


SETTING_CHECK_ARCSEC = 3.0  # a held axis's resolver against its command (10 x the scatter)


def axes_off_command(st: IsuDrivers, commanded: dict[int, float]) -> str | None:
    """Axes whose resolver does not read their last command (within SETTING_CHECK_ARCSEC),
    as the table reports them; None if every one does (asked only when a levelling fails:
    a seized axis answers a command within its in-position band with HOLD)."""
    off = []
    for ax, deg in commanded.items():
        res = resolver(st, ax)
        d = abs((res - deg + 180.0) % 360.0 - 180.0) * ARCSEC_PER_DEG
        if d > SETTING_CHECK_ARCSEC:
            off.append(f"axis {ax} reads {res:.7f} deg, commanded {deg:.7f} deg")
    return "; ".join(off) if off else None


def set_position(st: IsuDrivers, phi1: float, phi2: float | None, phi3: float, phi4: float,
                 level: bool, noise: NoiseSpec | None = None) -> PositionSet:
    """Move to (phi1, phi2, phi3, phi4); with ``level``, read the bubbles and correct phi1, phi3.

    phi2 None leaves the rotary axis alone (it is turning or about to). The levelling is
    confirmed by a second reading: level 1 must then read near zero and level 2 as before
    (the levels stand on the rotary platform, which phi3 does not turn). A confirmation
    that disagrees beyond ``K_READING`` sigma means one of the two readings was wrong: the
    table is corrected by the new reading and confirmed again (at most MAX_REREADS times,
    each recorded), then the step stops naming the levels.
    """
    noise = noise or SPEC
    axes = [(1, phi1), (3, phi3), (4, phi4)] + ([] if phi2 is None else [(2, phi2)])
    for ax, deg in axes:
        st.table.move(ax, deg)
    st.table.wait_still()
    if not level:
        return PositionSet((phi1, phi2 if phi2 is not None else float("nan"), phi3, phi4),
                           None, None)
    phi1_0, phi3_0 = phi1, phi3
    c1, c3 = read_levels(st)
    t_level = st.clock.now()
    relevelled: list[dict] = []
    while True:
        phi1 = phi1_0 + c1 / ARCSEC_PER_DEG
        phi3 = phi3_0 + c3 / ARCSEC_PER_DEG
        st.table.move(1, phi1)
        st.table.move(3, phi3)
        st.table.wait_still()
        v1, v3 = read_levels(st)
        sigma = level_check_sigma_arcsec(noise, st.clock.now() - t_level)
        tol = K_READING * sigma
        if level_check_z((v1, v3), (c1, c3), sigma) <= K_READING:
            break
        if len(relevelled) >= MAX_REREADS:
            stuck = axes_off_command(st, {1: phi1, 3: phi3})
            if stuck:  # the table did not make the correction: the levels are right
                raise Implausible(source_of(st.table), f"{stuck}: the levelling corrections "
                                  f"({c1:g}, {c3:g}) arcsec were not carried out (the levels "
                                  f"still read ({v1:g}, {v3:g}) arcsec)")
            raise Implausible(
                source_of(st.bubble_levels),
                f"levelling not confirmed after {len(relevelled)} corrections: levels read "
                f"({v1:g}, {v3:g}) arcsec after correcting by ({c1:g}, {c3:g}), expected "
                f"(0, {c3:g}) within {tol:.2g} arcsec: the readings do not agree")
        relevelled.append({"applied_arcsec": [c1, c3], "read_arcsec": [v1, v3],
                           "tolerance_arcsec": round(tol, 3)})
        c1, c3 = c1 + v1, v3
        t_level = st.clock.now()
    return PositionSet((phi1, phi2 if phi2 is not None else float("nan"), phi3, phi4),
                       (c1, c3), t_level, (v1, v3), relevelled)


def patch(st: IsuDrivers, wiring: dict[int, tuple[str | None, str | None, str]]) -> None:
    """Clear the panel, then counter -> (X line, Y line or None, Z line)."""
    st.patch_panel.clear_all()
    for c, (x, y, z) in wiring.items():
        if x:
            st.patch_panel.connect(x, c, "X")
        if y:
            st.patch_panel.connect(y, c, "Y")
        st.patch_panel.connect(z, c, "Z")


def patch_check_counter(st: IsuDrivers, counter: int, k: int) -> None:
    """Connect gyro k's + and - lines to a check counter's X and Y (its Z stays)."""
    st.patch_panel.connect(f"G{k}+", counter, "X")
    st.patch_panel.connect(f"G{k}-", counter, "Y")


@dataclass
class Gate:
    readings: dict[int, int]
    t_oper: float
    t_done: float
    t_each: dict[int, float] = field(default_factory=dict)  # when each counter was operated


def run_counters(st: IsuDrivers, presets: dict[int, int], timeout: float,
                 diagnose: Callable[[], str | None] | None = None) -> Gate:
    """Set presets, switch every counter to operate, wait for each print-out, then standby.

    ``diagnose``: asked when a counter fails to print (its gate never closed); if it names a
    cause outside the counters (the table's rotary axis not turning under a gate on its
    pulses), the step stops with that cause, naming that instrument.
    """
    for c, n in presets.items():
        st.counters[c].set_preset(n)
        st.counters[c].discard_readings()
    t0 = st.clock.now()
    t_each = {}
    for c in presets:
        t_each[c] = st.clock.now()
        st.counters[c].operate()
    readings = {}
    try:
        for c in presets:
            readings[c] = st.counters[c].read(timeout=timeout)
    except DriverError as e:
        for c in presets:  # cancel waiting reads (device clear), leave every counter in standby
            try:
                st.counters[c].clear()
                st.counters[c].standby()
            except DriverError:
                pass
        cause = diagnose() if diagnose is not None else None
        if cause is not None:
            raise Implausible(source_of(st.table), f"{cause} ({e})") from e
        raise
    for c in presets:
        st.counters[c].standby()
        st.counters[c].discard_readings()  # later gates printed while others still ran
    return Gate(readings, t0, st.clock.now(), t_each)


def check_repeated_counts(st: IsuDrivers, gate: Gate, repeats: dict[int, int],
                          gate_s: float | None) -> dict[str, int]:
    """Counters that counted the same line over the same gate must agree. ``gate_s`` None:
    the gate is a number of the table's rotation pulses, opened on the same pulse for
    every counter (no pulse falls between their switches to operate), so the counts are
    equal to a pulse; else a preset of clock ticks, each counter's gate opened at its own
    switch to operate, so they differ by the pulses of those few ms (2 + rate x the time
    between the switches). Beyond that one reading is garbled: Implausible naming both
    counters. Returns the differences found (main counter -> difference)."""
    out = {}
    for c, main in repeats.items():
        if c not in gate.readings or main not in gate.readings:
            continue
        a, b = gate.readings[main], gate.readings[c]
        if gate_s is None:
            allowed = 1.0
        else:
            rate = max(abs(a), abs(b)) / gate_s if gate_s > 0 else 0.0
            allowed = 2.0 + rate * abs(gate.t_each[c] - gate.t_each[main])
        if abs(a - b) > allowed:
            raise Implausible(
                f"{source_of(st.counters[main])} and {source_of(st.counters[c])}",
                f"counted the same line over the same gate as {a} and {b} (allowed "
                f"difference {allowed:.3g}): one reading is garbled")
        out[str(main)] = b - a
    return out


TURN_RATE_TOLERANCE = 1e-3  # relative: the table's mean rate over whole turns (data sheet)


def check_turns_clock(st: IsuDrivers, counter: int, ticks: int, pulses: int, s1: float,
                      s_phi: float, rate_deg_s: float) -> float:
    """Table rate (deg/s) from a counter's clock ticks over whole turns; it must be the
    commanded rate within TURN_RATE_TOLERANCE, else that counter's reading is wrong."""
    w = s_phi * pulses / (ticks * s1) if ticks > 0 else math.inf
    if not abs(w - abs(rate_deg_s)) <= TURN_RATE_TOLERANCE * abs(rate_deg_s):
        raise Implausible(source_of(st.counters[counter]),
                          f"{ticks} clock ticks over {pulses} rotation pulses make the table "
                          f"turn at {w:.7g} deg/s, commanded {abs(rate_deg_s):g} deg/s: the "
                          "reading is wrong")
    return w


def rotary_axis_turning(st: IsuDrivers, rate_deg_s: float, axis: int = 2,
                        tolerance: float = RATE_TOLERANCE) -> Callable[[], str | None]:
    """A ``diagnose`` for gates on the table's rotation pulses: None if ``axis`` turns at the
    commanded rate (within ``tolerance``, relative), else what the table reports."""

    def check() -> str | None:
        try:
            status = st.table.status()
            rate = st.table.rate(axis)
        except (DriverError, *PARSE_ERRORS):
            return None  # nothing known of the axis: the counter's own error stands
        if abs(rate - rate_deg_s) <= tolerance * abs(rate_deg_s):
            return None
        return (f"axis {axis} is not turning at the commanded {rate_deg_s:g} deg/s (STAT? "
                f"{','.join(status)}, RATE? {rate:g} deg/s): a gate on its rotation pulses "
                "cannot close")

    return check


def set_modes(st: IsuDrivers, counters: Iterable[int], mode: str) -> None:
    for c in counters:
        st.counters[c].set_mode(mode)
