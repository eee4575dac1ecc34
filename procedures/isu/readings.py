"""One reading of an instrument, checked on its own before a procedure uses it.

Each function reads what a check-sheet step needs (a level correction, a mirror's angles,
the resolvers of a table at rest, an axis's rate, a patch-panel connection) and refuses
what the instrument could not have meant: a value outside its range, a reply that is no
word it says, a reading that disagrees with the command the controller reports holding. A
refused reading is read again (at most ``MAX_REREADS`` times, each re-read recorded in the
enclosing ``plausibility.rereads()`` block), then the step stops naming the instrument.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from procedures.isu.plausibility import (
    MAX_REREADS,
    Implausible,
    autocollimator_reading,
    guarded,
    level_reading,
    note_reread,
    read_word,
    source_of,
)

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

ARCSEC_PER_DEG = 3600.0


def read_levels(st: IsuDrivers) -> tuple[float, float]:
    """One bubble-level reading inside the levels' range; an out-of-range reply is read
    again (at most MAX_REREADS times) before the step stops naming the levels."""
    refused: list[list[float]] = []
    while True:
        raw = st.bubble_levels.corrections()
        try:
            got = level_reading(st.bubble_levels, raw)
        except Implausible:
            if len(refused) == MAX_REREADS:
                raise
            refused.append([float(x) for x in raw])
            continue
        if refused:
            note_reread({"instrument": st.bubble_levels.name, "what": "level corrections",
                         "was": refused, "now": list(got)})
        return got


def read_mirror(st: IsuDrivers, k: int) -> tuple[float, float]:
    """One autocollimator k reading (azimuth, zenith, deg) the mount and field allow; an
    impossible one is read again (at most MAX_REREADS times), no return stops the step."""
    ac = st.autocollimators[k]
    refused: list[list[float]] = []
    while True:
        m = ac.measure()
        if m is None:
            raise Implausible(source_of(ac), f"no return from mirror {k} while reading it")
        try:
            got = autocollimator_reading(ac, m)
        except Implausible:
            if len(refused) == MAX_REREADS:
                raise
            refused.append([float(x) for x in m])
            continue
        if refused:
            note_reread({"instrument": ac.name, "what": f"mirror {k} azimuth and zenith",
                         "was": refused, "now": list(got)})
        return got


def resolvers(st: IsuDrivers) -> tuple[float, float, float, float]:
    """The four resolver readings (a reply the driver cannot read is read again)."""
    return guarded(st.table, "resolvers", st.table.positions)


def resolver(st: IsuDrivers, axis: int) -> float:
    """One axis's resolver reading (a reply the driver cannot read is read again)."""
    return guarded(st.table, f"axis {axis} resolver", lambda: st.table.position(axis))


RESOLVER_REPEAT_ARCSEC = 0.5  # a holding axis's resolver reads the same within this


def steady_resolvers(st: IsuDrivers, first: tuple[float, ...] | None = None
                     ) -> tuple[float, float, float, float]:
    """The resolvers of a table at rest, read until two consecutive readings agree within
    RESOLVER_REPEAT_ARCSEC (``first``: a reading already taken at this setting, else one is
    taken); at most MAX_REREADS more readings, recorded, then the step stops naming the table."""

    def apart(a: Sequence[float], b: Sequence[float]) -> float:
        return max(abs((x - y + 180.0) % 360.0 - 180.0) for x, y in zip(a, b, strict=True))

    prev = tuple(first) if first is not None else resolvers(st)
    was: list[list[float]] = []
    while True:
        now = resolvers(st)
        if apart(now, prev) * ARCSEC_PER_DEG <= RESOLVER_REPEAT_ARCSEC:
            if was:
                note_reread({"instrument": st.table.name, "what": "resolvers", "was": was,
                             "now": list(now)})
            return now
        if len(was) == MAX_REREADS:
            raise Implausible(source_of(st.table), f"resolver readings {list(prev)} and "
                              f"{list(now)} deg of the table at rest disagree after "
                              f"{len(was)} re-reads (garbled replies)")
        was.append(list(prev))
        prev = now


IN_POSITION_ARCSEC = 10.0  # the controller holds an axis within this of its command


def axis_in_position(st: IsuDrivers, axis: int, commanded_deg: float) -> float:
    """The resolver of an axis holding at ``commanded_deg``: it must read within the
    controller's in-position band of the command; a reading beyond it is read again (at most
    MAX_REREADS times, recorded), then the step stops naming the table."""
    return _table_reading(
        st, f"axis {axis} resolver", lambda: resolver(st, axis),
        lambda deg: abs((deg - commanded_deg + 180.0) % 360.0 - 180.0) * 3600.0
        <= IN_POSITION_ARCSEC,
        lambda was: f"axis {axis} holds but its resolver reads {was} deg, commanded "
        f"{commanded_deg} deg")


def _table_reading(st: IsuDrivers, what: str, read: Callable[[], float],
                   ok: Callable[[float], bool], refusal: Callable[[list[float]], str]) -> float:
    """A table reading that must pass ``ok``: read again (at most MAX_REREADS times, the
    re-read recorded), then Implausible naming the table with ``refusal`` of the readings."""
    was: list[float] = []
    while True:
        value = read()
        if ok(value):
            if was:
                note_reread({"instrument": st.table.name, "what": what, "was": was,
                             "now": value})
            return value
        if len(was) == MAX_REREADS:
            raise Implausible(source_of(st.table), refusal(was + [value]))
        was.append(value)


def panel_connection(st: IsuDrivers, counter: int, inp: str, lines: set[str],
                     first: str | None = None) -> str | None:
    """What the panel connects to a counter input: None or one of its ``lines``. Any other
    reply (a NONE that lost a letter) is garbled: read again, then stop naming the panel.
    ``first``: the reply already received."""
    pp = st.patch_panel
    words = ("NONE", *sorted(lines))
    r = read_word(pp, lambda: pp.connection(counter, inp) or "NONE", words,
                  f"reply to 'CONN? C{counter} {inp}'", first)
    return None if r == "NONE" else r


RATE_TOLERANCE = 0.01  # relative: a turning axis at its commanded rate (servo and reading)


def axis_rate(st: IsuDrivers, axis: int, commanded_deg_s: float) -> float:
    """The rate of an axis the controller reports turning at ``commanded_deg_s``: a reply
    off by more than RATE_TOLERANCE is read again (at most MAX_REREADS times, recorded), then
    the step stops naming the table and the axis."""
    return _table_reading(
        st, f"axis {axis} rate",
        lambda: guarded(st.table, f"axis {axis} rate", lambda: st.table.rate(axis)),
        lambda r: abs(r - commanded_deg_s) <= RATE_TOLERANCE * abs(commanded_deg_s),
        lambda was: f"axis {axis} reports turning but at {was} deg/s, commanded "
        f"{commanded_deg_s:g} deg/s")


AXIS_STATES = ("HOLD", "MOVING", "ROTATING", "ACCEL")


def table_status(st: IsuDrivers) -> list[str]:
    """The four axes' states, each a word the controller says (a garbled ``STAT?`` reply,
    e.g. a HOLD that lost its H, is read again; then the step stops naming the table)."""
    was: list[str] = []
    while True:
        axes = st.table.status()
        if len(axes) == 4 and all(a in AXIS_STATES for a in axes):
            if was:
                note_reread({"instrument": st.table.name, "what": "axis states",
                             "was": was, "now": ",".join(axes)})
            return axes
        if len(was) == MAX_REREADS:
            raise Implausible(source_of(st.table), f"replies to 'STAT?' {was + [','.join(axes)]}"
                              f" are not four of {', '.join(AXIS_STATES)} (garbled replies)")
        was.append(",".join(axes))
