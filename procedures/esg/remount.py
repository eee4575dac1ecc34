"""Sheet ESG-PA2: pickoff 2 aligned with the case remounted (report 004, "Mirror and
Pickoff Alignment": after the first pickoff "the procedure is then repeated" for the
second, with the other reference mirror along the table axis; issue 20).

Our design where the report is silent (docs/esg-options.md): before the calibration's
step 1, with the rotor at rest, the case is set on the plate with mirror 2 along the
spindle (head ``MOUNT 2``: c3 and c1 take the places of c2 and c3), the mount is shimmed
by the theodolite until mirror 2 cones within 3 arcsec (as step 1 does for mirror 1), the
spindle is laid level and north with c1 up, and the rotor is spun up with damping, so the
spin axis s settles on c1: across the spindle, where pickoff 2 reads near the equator,
and vertical, where the unbalance drift vanishes and the Earth's rate turns s about the
spindle only (it leaves pickoff 2's colatitude alone). A spindle turn then gives pickoff
2's coning as ESG-PA gives pickoff 1's; above 15 arcsec pickoff 2 is translated along c3,
c1 (``XLATE 2``) by the turn's first harmonic, the angle of s about the spindle taken
from pickoff 3 (procedures.esg.alignment), and measured again. Then the rotor is braked
and the case mounted back with mirror 1 along the spindle (``MOUNT 1``): step 1 shims it.
"""

from __future__ import annotations

import numpy as np

from procedures.esg import alignment
from procedures.esg import geometry as geo
from procedures.esg.acquisition import (
    TURN_INTERNAL,
    EsgPlan,
    _mirror_coning,
    _move_head,
    _move_table,
    _pickoff_coning,
    brake,
    plan_colatitude_deg,
    plan_slope_per_deg,
    refuse_coning,
    shim_to_limit,
    spin_up_damped,
)
from procedures.runner import CheckSheetRun, Run
from station.drivers.esg import EsgDrivers
from station.errors import CheckFailed

PICKOFF, PARTNER = 2, 3  # the pickoff along the spindle; the one along c3 gives psi
# with mirror 2 mounted, c1 is the spindle frame's third axis
C1_IN_SPINDLE_FRAME = np.array([0.0, 0.0, 1.0])


def gamma_c1_up() -> float:
    """The spindle angle (of 0, 90, 180, 270) that puts c1 up with the spindle level and
    north (nominal geometry)."""
    return max((0.0, 90.0, 180.0, 270.0),
               key=lambda g: float((geo.r_lc(0.0, 0.0, g) @ C1_IN_SPINDLE_FRAME)[2]))


def _psi_deg(turn: dict) -> float:
    """Angle of s about the spindle at spindle angle 0, from c3 towards c1: the turn's
    first spindle angle plus pickoff 3's colatitude there (the drawing's pattern)."""
    if turn["partner_cr"] is None:
        raise CheckFailed("pickoff 3 off the pattern at the turn's start: s is not near c1")
    return float(turn["spindle_deg"][0]) + turn["theta_partner_deg"]


def _turn(st: EsgDrivers, plan: EsgPlan, gamma0: float) -> dict:
    turn = _pickoff_coning(st, plan, gamma0, PICKOFF, PARTNER)
    cr = turn["partner_cr"]
    turn["theta_partner_deg"] = None if cr is None else plan_colatitude_deg(cr, plan)
    return turn


def _reading(turn: dict) -> dict:
    return {k: v for k, v in turn.items() if k not in TURN_INTERNAL}


def pickoff2_alignment(st: EsgDrivers, run: Run, plan: EsgPlan) -> dict:
    """Sheet ESG-PA2 (module doc); its journal form: the last coning turn's figures."""
    limit = plan.pickoff_coning_limit_arcsec
    with run.sheet("ESG-PA2", "Pickoff 2 alignment by coning, mirror 2 along the "
                   "spindle") as sh:
        remount_and_shim(st, plan, sh, 2)
        gamma0 = gamma_c1_up()
        with sh.step("PA2.spin", "spindle level and north, c1 up; spin up to operating "
                     "speed with damping; damping off") as s:
            _move_table(st, plan, az=0.0, tilt=0.0)
            gamma0 = _move_head(st, plan, gamma0)
            spin_up_damped(st, plan)
            s.reading = {"settings_deg": [0.0, 0.0, gamma0], **st.console.status()}
        with sh.step("PA2.1", "pickoff 2 count ratio over one spindle turn (and back to "
                     "the start); first harmonic = coning of pickoff 2") as s:
            turn = _turn(st, plan, gamma0)
            s.reading = _reading(turn)
        adjusted = 0
        while turn["coning_arcsec"] > limit and adjusted < plan.alignment_iterations:
            adjusted += 1
            with sh.step(f"PA2.translate-{adjusted}", "pickoff 2 translated in its fixture "
                         "along c3, c1 by the coning's first harmonic; coning measured "
                         "again") as s:
                h, psi = turn["harmonic_cr"], _psi_deg(turn)
                a, b = alignment.translation_arcsec(h[0], h[1], plan_slope_per_deg(90.0, plan),
                                                    psi)
                st.console.translate(PICKOFF, a, b)
                turn = _turn(st, plan, gamma0)
                s.reading = {"translation_arcsec": [a, b], "psi_deg": psi, **_reading(turn)}
        refuse_coning(turn, limit, PICKOFF)
        with sh.step("PA2.remount", "rotor braked to rest; case mounted back with mirror 1 "
                     "along the spindle (step 1 shims it)") as s:
            brake(st, plan)
            st.head.mount(1)
            s.reading = {"spin_rps": st.console.speed()}
    return {"coning_arcsec": turn["coning_arcsec"], "sigma_arcsec": turn["sigma_arcsec"],
            "translations": adjusted}


def remount_and_shim(st: EsgDrivers, plan: EsgPlan, sh: CheckSheetRun, mirror: int,
                     prefix: str = "PA2") -> float:
    """Steps ``<prefix>.mount``, ``<prefix>.shim-k``: the case set on the plate with
    ``mirror`` along the spindle, its coning in the theodolite, and shims until it is
    within the limit; the last coning radius."""
    with sh.step(f"{prefix}.mount", f"rotor at rest; case set on the plate with mirror {mirror} "
                 "along the spindle; theodolite readings over one spindle turn") as s:
        _move_head(st, plan, 0.0)
        st.head.mount(mirror)
        turn = _mirror_coning(st, plan)
        s.reading = turn
    return shim_to_limit(st, plan, sh, turn, prefix)
