"""Laboratory turn-on (Chart I-1).

The report leaves Chart I-1 blank, to be written once the laboratory is built. This sheet is
the project's own: every instrument answers on its link, the master oscillator is locked and
its countdowns are as configured, the counters pass their self-tests and stand by, the patch
panel is cleared, the table's interlock is closed and it homes, the IEU is idle and without
error, the bubble levels read, and the ISU warms up before anything is measured.

Every status reply must be a word the instrument reports (a garbled one is read again,
``procedures.isu.plausibility.read_word``), so a stop names the instrument and what it truly
said; the oscillator's frequency and countdowns, which every later computation uses from
this sheet, are each read twice and must agree.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from procedures.isu.plausibility import (
    Implausible,
    guarded,
    read_agreeing,
    read_word,
    rereads,
    source_of,
    with_rereads,
)
from procedures.isu.readings import panel_connection, read_levels, resolvers, table_status
from procedures.runner import Run
from station.errors import CheckFailed

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

CHART = "I-1"
OSCILLATOR_STATUS = ("LOCKED", "UNLOCKED")
SELF_TEST = ("PASS", "FAIL")
COUNTER_STATES = ("STBY", "OPER")
INTERLOCK = ("CLOSED", "OPEN")
TITLE = "Laboratory turn-on"
COUNTER_INPUTS = ("X", "Y", "Z")
HOME_TOLERANCE_ARCSEC = 10.0  # homed resolvers within this of 0 deg (resolver error ~1 arcsec)
DEFAULT_WARMUP_S = 1800.0  # ISU warm-up before the survey or calibration, simulated seconds


def _from_zero_arcsec(deg: float) -> float:
    """Distance of a resolver reading from 0 deg (axes 2-4 wrap to [0, 360)), arcsec."""
    d = (deg + 180.0) % 360.0 - 180.0
    return abs(d) * 3600.0


def turn_on(station: IsuDrivers, run: Run, warmup_s: float = DEFAULT_WARMUP_S) -> None:
    """Tick Chart I-1 on ``station``; a failed check raises ProcedureError (chart, step)."""
    if warmup_s < 0:
        raise ValueError(f"warm-up time must be >= 0 s, got {warmup_s}")
    st = station
    with run.sheet(CHART, TITLE) as sheet:
        with sheet.step("1", "Every instrument answers on its link; record identities") as s:
            ids = {
                "oscillator": st.oscillator.identify(),
                "table": st.table.identify(),
                "patch_panel": st.patch_panel.identify(),
                "bubble_levels": st.bubble_levels.identify(),
                "ieu": st.ieu.identify(),
            }
            ids |= {f"counter{i}": c.identify() for i, c in sorted(st.counters.items())}
            ids |= {f"autocollimator{i}": a.identify() for i, a in st.autocollimators.items()}
            s.reading = ids

        with sheet.step("2", "Master oscillator locked and passes its self-test") as s, \
                rereads() as rr:
            osc = st.oscillator
            status = read_word(osc, osc.status, OSCILLATOR_STATUS, "status")
            test = read_word(osc, osc.self_test, SELF_TEST, "self-test")
            if status != "LOCKED":
                raise Implausible(source_of(osc), f"status {status!r}, expected LOCKED")
            if test != "PASS":
                raise Implausible(source_of(osc), f"self-test {test!r}")
            s.reading = with_rereads({"status": status, "self_test": test}, rr)

        text3 = "Record oscillator frequency and countdown ratios (S1^T, S2^T)"
        with sheet.step("3", text3) as s, rereads() as rr:
            osc = st.oscillator
            f = read_agreeing(osc, lambda: guarded(osc, "frequency", osc.nominal_hz),
                              "nominal frequency")
            d1 = read_agreeing(osc, lambda: guarded(osc, "countdown 1", lambda: osc.divider(1)),
                               "countdown ratio 1")
            d2 = read_agreeing(osc, lambda: guarded(osc, "countdown 2", lambda: osc.divider(2)),
                               "countdown ratio 2")
            if f <= 0 or d1 <= 0 or d2 <= 0:
                raise Implausible(source_of(osc),
                                  f"implausible settings: {f} Hz, /{d1}, /{d2}")
            s.reading = with_rereads({
                "nominal_hz": f,
                "divider_1": d1,
                "divider_2": d2,
                "s1_t_s": d1 / f,  # counters' clock, seconds per pulse
                "s2_t_s": d2 / f,  # IEU timer, seconds per pulse
            }, rr)

        with sheet.step("4", "Counters 1-6 pass their self-tests and are set to standby") as s, \
                rereads() as rr:
            out = {}
            for i, c in sorted(st.counters.items()):
                test = read_word(c, c.self_test, SELF_TEST, "self-test")
                if test != "PASS":
                    raise Implausible(source_of(c), f"self-test {test!r}")
                c.standby()
                state = read_word(c, c.state, COUNTER_STATES, "state")
                if state != "STBY":
                    raise Implausible(source_of(c), f"reports {state!r} after standby")
                out[str(i)] = {"self_test": test, "state": state}
            s.reading = with_rereads(out, rr)

        with sheet.step("5", "Patch panel cleared: no counter input connected") as s, \
                rereads() as rr:
            pp = st.patch_panel
            pp.clear_all()
            replies = {(i, inp): pp.connection(i, inp) for i in sorted(st.counters)
                       for inp in COUNTER_INPUTS}
            lines = pp.lines()
            known = set(lines)
            left = {}
            for (i, inp), line in replies.items():
                if line is not None and line not in known:  # garbled: read it again
                    line = panel_connection(st, i, inp, known, first=line)
                if line is not None:
                    left[f"C{i}{inp}"] = line
            if left:
                raise Implausible(source_of(pp), f"connections left after clearing: {left}")
            s.reading = with_rereads({"lines": lines, "connections": {}}, rr)

        with sheet.step("6", "Table interlock closed (safe to move)") as s, rereads() as rr:
            ilck = read_word(st.table, st.table.interlock, INTERLOCK, "interlock")
            if ilck != "CLOSED":
                raise Implausible(source_of(st.table), f"interlock {ilck!r}: motion inhibited")
            s.reading = with_rereads({"interlock": ilck}, rr)

        with sheet.step("7", "Home the table; all axes hold with resolvers near 0 deg") as s:
            st.table.home()
            st.table.wait_still()
            pos = resolvers(st)
            off = [_from_zero_arcsec(p) for p in pos]
            if max(off) > HOME_TOLERANCE_ARCSEC:
                raise Implausible(
                    source_of(st.table),
                    f"homed resolvers {pos} deg: more than {HOME_TOLERANCE_ARCSEC:g} arcsec "
                    "from 0")
            s.reading = {
                "resolvers_deg": list(pos),
                "status": table_status(st),
                "max_from_zero_arcsec": max(off),
            }

        with sheet.step("8", "IEU idle and reporting no error") as s:
            ieu_status = st.ieu.status()
            if int(ieu_status.get("ErrorCode", 0)) != 0:
                raise Implausible(source_of(st.ieu),
                                  f"reports error code {ieu_status['ErrorCode']}")
            if int(ieu_status.get("State", 0)) != 0:
                st.ieu.stop()
                ieu_status = st.ieu.status()
            s.reading = {k: int(v) for k, v in ieu_status.items()}

        with sheet.step("9", "Bubble levels readable (level corrections, arcsec)") as s, \
                rereads() as rr:
            c1, c3 = read_levels(st)
            s.reading = with_rereads({"phi1_corr_arcsec": c1, "phi3_corr_arcsec": c3}, rr)

        with sheet.step("10", f"ISU warm-up: wait {warmup_s:g} s with the table at rest") as s:
            t0 = st.clock.now()
            st.clock.sleep(warmup_s)
            s.reading = {"start_s": t0, "end_s": st.clock.now(), "warmup_s": warmup_s}

        text11 = "After warm-up: oscillator still locked, table still holding"
        with sheet.step("11", text11) as s, rereads() as rr:
            status = read_word(st.oscillator, st.oscillator.status, OSCILLATOR_STATUS,
                               "status")
            axes = table_status(st)
            if status != "LOCKED":
                raise Implausible(source_of(st.oscillator),
                                  f"status {status!r} after warm-up")
            if any(a != "HOLD" for a in axes):
                raise Implausible(source_of(st.table),
                                  f"axes {axes} after warm-up, expected HOLD")
            s.reading = with_rereads({"oscillator": status, "table": axes}, rr)


def oscillator_periods(run: Run) -> tuple[float, float]:
    """(S1^T, S2^T) in seconds as Chart I-1 step 3 recorded them in this run: every later
    computation uses these, not a fresh reading, so one garbled reply cannot change them."""
    done = run.check_sheets.get(CHART)
    rec = next((r for r in done.steps if r.number == "3"), None) if done else None
    if rec is None or not isinstance(rec.reading, dict):
        raise CheckFailed("turn-on (Chart I-1) step 3 has not recorded the oscillator's "
                          "countdowns in this run")
    return float(rec.reading["s1_t_s"]), float(rec.reading["s2_t_s"])
