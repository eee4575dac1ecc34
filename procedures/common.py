"""Operations every calibration check-sheet repeats: set a position, patch, run counters."""

from __future__ import annotations

from dataclasses import dataclass

from station.errors import DriverError

ARCSEC_PER_DEG = 3600.0


@dataclass
class PositionSet:
    """A table setting as commanded, with the bubble-level corrections applied (deg)."""

    phi: tuple[float, float, float, float]
    level_arcsec: tuple[float, float] | None
    t_level: float | None


def set_position(st, phi1: float, phi2: float | None, phi3: float, phi4: float,
                 level: bool) -> PositionSet:
    """Move to (phi1, phi2, phi3, phi4); with ``level``, read the bubbles and correct phi1, phi3.

    phi2 None leaves the rotary axis alone (it is turning or about to).
    """
    axes = [(1, phi1), (3, phi3), (4, phi4)] + ([] if phi2 is None else [(2, phi2)])
    for ax, deg in axes:
        st.table.move(ax, deg)
    st.table.wait_still()
    corr = None
    t_level = None
    if level:
        c1, c3 = st.bubble_levels.corrections()
        t_level = st.clock.now()
        corr = (c1, c3)
        phi1 = phi1 + c1 / ARCSEC_PER_DEG
        phi3 = phi3 + c3 / ARCSEC_PER_DEG
        st.table.move(1, phi1)
        st.table.move(3, phi3)
        st.table.wait_still()
    return PositionSet((phi1, phi2 if phi2 is not None else float("nan"), phi3, phi4), corr,
                       t_level)


def patch(st, wiring: dict[int, tuple[str | None, str | None, str]]) -> None:
    """Clear the panel, then counter -> (X line, Y line or None, Z line)."""
    st.patch_panel.clear_all()
    for c, (x, y, z) in wiring.items():
        if x:
            st.patch_panel.connect(x, c, "X")
        if y:
            st.patch_panel.connect(y, c, "Y")
        st.patch_panel.connect(z, c, "Z")


@dataclass
class Gate:
    readings: dict[int, int]
    t_oper: float
    t_done: float


def run_counters(st, presets: dict[int, int], timeout: float) -> Gate:
    """Set presets, switch every counter to operate, wait for each print-out, then standby."""
    for c, n in presets.items():
        st.counters[c].set_preset(n)
        st.counters[c].discard_readings()
    t0 = st.clock.now()
    for c in presets:
        st.counters[c].operate()
    readings = {}
    try:
        for c in presets:
            readings[c] = st.counters[c].read(timeout=timeout)
    except DriverError:
        for c in presets:  # cancel waiting reads (device clear), leave every counter in standby
            try:
                st.counters[c].clear()
                st.counters[c].standby()
            except DriverError:
                pass
        raise
    for c in presets:
        st.counters[c].standby()
        st.counters[c].discard_readings()  # later gates printed while others still ran
    return Gate(readings, t0, st.clock.now())


def set_modes(st, counters, mode: str) -> None:
    for c in counters:
        st.counters[c].set_mode(mode)
