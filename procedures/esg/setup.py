"""Processor and lamp adjustments with the rotor at speed (report 004, "Before data taking").

"The gyro is spun up to operating speed and attitude such that one pickoff is looking at the
very extremity of the pattern": after step 2 the case is turned (nominal geometry, the spin
axis taken on the spindle) so that pickoff 2 looks just inside the pattern's top colatitude,
which puts pickoff 3 on the equator. There, on the processor's scope:

* lamp currents: "By adjusting the lamp currents, the height of the pickoff pulses can be
  made uniform ... adjusted to give a height of 2.1 vpp (this is the minimum height of the
  three before adjustment)": each lamp to min height / its height;
* delay: "The time from the trailing edge of the logic line to the trailing edge of the
  pattern line is measured and the delay of the multivibrator is adjusted to be this time
  plus 20 microseconds" (rounded up to a whole microsecond);
* discriminator: the report adjusts it "to a point just before the pulse disappears" at the
  extremity, where pulses are widest; that would reject the narrower genuine pulses at the
  equator (docs/esg.md, departures), so it is set 3 us below the narrowest genuine pulse on
  the scope, the equator's logic line on pickoff 3 (within the processor's 2..24 us).

The case then goes back (spindle on the polar axis) and the rotor is damped again before
step 3, since it drifted while the case was turned.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from procedures.esg import geometry as geo
from procedures.esg.readout import pickoffs_from_mirrors
from procedures.runner import Run
from station.drivers.esg import EsgDrivers
from station.errors import CheckFailed

# colatitudes of pickoff 2 tried in turn, just inside the pattern's end (43 deg on the report's
# rotor; the spin axis drifts while the case is turned, so a first setting may leave the
# pickoff off the pattern)
EXTREMITY_STEPS_DEG = (0.6, 1.0, 1.5, 2.0)
EXTREMITY_DEG = tuple(round(43.0 + d, 6) for d in EXTREMITY_STEPS_DEG)
DISC_MARGIN_US = 3.0
DELAY_MARGIN_US = 20.0
DISC_RANGE_US = (2.0, 24.0)


def extremity_direction(colatitude_deg: float, mirror_angle_deg: float) -> np.ndarray:
    """Spin axis in case axes with pickoff 2 at ``colatitude_deg`` and pickoff 3 on the
    equator (in the plane of pickoffs 1 and 2)."""
    th = math.radians(colatitude_deg)
    alpha = np.array([math.sin(th), math.cos(th), 0.0])
    return geo.unit(np.linalg.solve(pickoffs_from_mirrors(mirror_angle_deg), alpha))


def discriminator_us(narrowest_us: float) -> float:
    """The width discriminator: DISC_MARGIN_US below the narrowest genuine pulse, whole us."""
    lo, hi = DISC_RANGE_US
    return float(min(hi, max(lo, math.floor(narrowest_us - DISC_MARGIN_US))))


def delay_us(logic_to_line_us: float) -> float:
    """The logic-line delay gate: the extremity's logic-to-line time plus 20 us."""
    return float(math.ceil(logic_to_line_us + DELAY_MARGIN_US))


def extremity_setup(st: EsgDrivers, run: Run, latitude_deg: float, mirror_angle_deg: float,
                    move: Callable[[float, float, float], None],
                    damp: Callable[[], None], top_deg: float = 43.0) -> dict:
    """Sheet ESG-DPX; ``move(az, tilt, gamma)`` and ``damp()`` are the acquisition's own
    moves; ``top_deg`` the pattern's end on the drawing. Returns the settings made."""
    tried = tuple(round(top_deg + d, 6) for d in EXTREMITY_STEPS_DEG)
    s_lab = geo.from_az_el(0.0, latitude_deg)  # after step 2 the spin axis is on the spindle
    with run.sheet("ESG-DPX", "Processor and lamp adjustments at the pattern extremity") as sh:
        with sh.step("DPX.1", "case turned: pickoff 2 at the pattern extremity, pickoff 3 "
                     "at the equator; pulses on the scope") as s:
            scope: dict[int, dict | None] = {}
            for th in tried:
                a, e, g = geo.point_case(extremity_direction(th, mirror_angle_deg), s_lab)
                move(a, e, g)
                scope = {k: st.processor.scope(k) for k in (1, 2, 3)}
                if scope[2] is not None and scope[3] is not None:
                    break
            s.reading = {"pickoff2_colatitude_deg": th, "settings_deg": [a, e, g],
                         "scope": {str(k): v for k, v in scope.items()}}
            if scope[2] is None or scope[3] is None:
                raise CheckFailed("pickoff 2 or 3 sees no pattern at the extremity setting "
                                  f"(tried pickoff 2 at {', '.join(map(str, tried))} "
                                  "deg)")
        on = {k: v for k, v in scope.items() if v is not None}
        with sh.step("DPX.2", "lamp currents: every pickoff's pulses to the lowest height") as s:
            for k in on:
                st.console.lamp(k, 100.0)
            before = {k: st.processor.scope(k) for k in on}
            heights = {k: v["height_v"] for k, v in before.items() if v is not None}
            low = min(heights.values())
            for k, h in heights.items():
                st.console.lamp(k, 100.0 * low / h)
            after = {k: st.processor.scope(k) for k in on}
            s.reading = {"heights_before_v": {str(k): v for k, v in heights.items()},
                         "lamp_percent": {str(k): st.console.lamp_reading(k) for k in on},
                         "heights_after_v": {str(k): (v or {}).get("height_v")
                                             for k, v in after.items()}}
        with sh.step("DPX.3", "pulse-width discriminator below the narrowest genuine pulse "
                     "(the equator's logic line on pickoff 3)") as s:
            narrowest = min(min(v["widths_us"]) for v in on.values())
            disc = discriminator_us(narrowest)
            st.processor.discriminator(disc)
            s.reading = {"narrowest_us": narrowest, "set_us": disc,
                         "read_back_us": st.processor.settings()["min_width_us"]}
        with sh.step("DPX.4", "logic-line delay: the longest logic-to-line time on the "
                     "scope (the extremity's; the equator's where longer) plus 20 us") as s:
            # beyond the report: on its great circle the extremity's time is the longest;
            # on a cosine pattern ending past 45 deg the equator's is (pickoff 3 shows it)
            t_ll = on[2]["logic_to_line_us"]
            t_eq = on[3]["logic_to_line_us"]  # DPX.1 stopped unless 2 and 3 see pulses
            dly = delay_us(max(t_ll, t_eq))
            st.processor.delay(dly)
            s.reading = {"logic_to_line_us": t_ll, "equator_logic_to_line_us": t_eq,
                         "set_us": dly,
                         "read_back_us": st.processor.settings()["logic_delay_us"]}
        with sh.step("DPX.5", "case back: spindle on the polar axis; rotor damped") as s:
            move(0.0, latitude_deg, 0.0)
            damp()
            s.reading = st.console.status()
    return {"min_width_us": disc, "logic_delay_us": dly, "lamp_heights_v": low}
