"""Laboratory turn-on (Chart I-1).

The report leaves Chart I-1 blank, to be written once the laboratory is built. This sheet is
the project's own: every instrument answers on its link, the master oscillator is locked and
its countdowns are as configured, the counters pass their self-tests and stand by, the patch
panel is cleared, the table's interlock is closed and it homes, the IEU is idle and without
error, the bubble levels read, and the ISU warms up before anything is measured.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from procedures.runner import Run

if TYPE_CHECKING:
    from station.rack import Station

CHART = "I-1"
TITLE = "Laboratory turn-on"
COUNTER_INPUTS = ("X", "Y", "Z")
HOME_TOLERANCE_ARCSEC = 10.0  # homed resolvers within this of 0 deg (resolver error ~1 arcsec)
DEFAULT_WARMUP_S = 1800.0  # ISU warm-up before the survey or calibration, simulated seconds


def _from_zero_arcsec(deg: float) -> float:
    """Distance of a resolver reading from 0 deg (axes 2-4 wrap to [0, 360)), arcsec."""
    d = (deg + 180.0) % 360.0 - 180.0
    return abs(d) * 3600.0


def turn_on(station: Station, run: Run, warmup_s: float = DEFAULT_WARMUP_S) -> None:
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

        with sheet.step("2", "Master oscillator locked and passes its self-test") as s:
            status = st.oscillator.status()
            test = st.oscillator.self_test()
            if status != "LOCKED":
                raise RuntimeError(f"master oscillator status {status!r}, expected LOCKED")
            if test != "PASS":
                raise RuntimeError(f"master oscillator self-test {test!r}")
            s.reading = {"status": status, "self_test": test}

        with sheet.step("3", "Record oscillator frequency and countdown ratios (S1^T, S2^T)") as s:
            f = st.oscillator.nominal_hz()
            d1, d2 = st.oscillator.divider(1), st.oscillator.divider(2)
            if f <= 0 or d1 <= 0 or d2 <= 0:
                raise RuntimeError(f"implausible oscillator settings: {f} Hz, /{d1}, /{d2}")
            s.reading = {
                "nominal_hz": f,
                "divider_1": d1,
                "divider_2": d2,
                "s1_t_s": d1 / f,  # counters' clock, seconds per pulse
                "s2_t_s": d2 / f,  # IEU timer, seconds per pulse
            }

        with sheet.step("4", "Counters 1-6 pass their self-tests and are set to standby") as s:
            out = {}
            for i, c in sorted(st.counters.items()):
                test = c.self_test()
                if test != "PASS":
                    raise RuntimeError(f"counter {i} self-test {test!r}")
                c.standby()
                state = c.state()
                if state != "STBY":
                    raise RuntimeError(f"counter {i} reports {state!r} after standby")
                out[str(i)] = {"self_test": test, "state": state}
            s.reading = out

        with sheet.step("5", "Patch panel cleared: no counter input connected") as s:
            st.patch_panel.clear_all()
            left = {
                f"C{i}{inp}": line
                for i in sorted(st.counters)
                for inp in COUNTER_INPUTS
                if (line := st.patch_panel.connection(i, inp)) is not None
            }
            if left:
                raise RuntimeError(f"connections left after clearing: {left}")
            s.reading = {"lines": st.patch_panel.lines(), "connections": {}}

        with sheet.step("6", "Table interlock closed (safe to move)") as s:
            ilck = st.table.interlock()
            if ilck != "CLOSED":
                raise RuntimeError(f"table interlock {ilck!r}: motion inhibited")
            s.reading = {"interlock": ilck}

        with sheet.step("7", "Home the table; all axes hold with resolvers near 0 deg") as s:
            st.table.home()
            st.table.wait_still()
            pos = st.table.positions()
            off = [_from_zero_arcsec(p) for p in pos]
            if max(off) > HOME_TOLERANCE_ARCSEC:
                raise RuntimeError(
                    f"homed resolvers {pos} deg: more than {HOME_TOLERANCE_ARCSEC:g} arcsec from 0"
                )
            s.reading = {
                "resolvers_deg": list(pos),
                "status": st.table.status(),
                "max_from_zero_arcsec": max(off),
            }

        with sheet.step("8", "IEU idle and reporting no error") as s:
            status = st.ieu.status()
            if int(status.get("ErrorCode", 0)) != 0:
                raise RuntimeError(f"IEU reports error code {status['ErrorCode']}")
            if int(status.get("State", 0)) != 0:
                st.ieu.stop()
                status = st.ieu.status()
            s.reading = {k: int(v) for k, v in status.items()}

        with sheet.step("9", "Bubble levels readable (level corrections, arcsec)") as s:
            c1, c3 = st.bubble_levels.corrections()
            s.reading = {"phi1_corr_arcsec": c1, "phi3_corr_arcsec": c3}

        with sheet.step("10", f"ISU warm-up: wait {warmup_s:g} s with the table at rest") as s:
            t0 = st.clock.now()
            st.clock.sleep(warmup_s)
            s.reading = {"start_s": t0, "end_s": st.clock.now(), "warmup_s": warmup_s}

        with sheet.step("11", "After warm-up: oscillator still locked, table still holding") as s:
            status = st.oscillator.status()
            axes = st.table.status()
            if status != "LOCKED":
                raise RuntimeError(f"master oscillator status {status!r} after warm-up")
            if any(a != "HOLD" for a in axes):
                raise RuntimeError(f"table axes {axes} after warm-up, expected HOLD")
            s.reading = {"oscillator": status, "table": axes}
