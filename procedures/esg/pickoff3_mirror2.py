"""Pickoff 3's tilt towards mirror 2, measured in a second remount after step 3 (report
004, "Mirror and Pickoff Alignment": pickoff 3 set perpendicular to both mirror normals by
a coning measurement adapted a little; issue 20). Our design, with ``pickoff3_mirror2``
(docs/esg-options.md):

The reversed-turn measurement of procedures.esg.pickoff3 needs the spin axis s along the
spindle and staying there. With mirror 2 along the spindle the damping coil (c1) is
across it, so s is first damped onto c1 with c1 pointed at the drift equilibrium that
step 3 measured (the unbalance drift k scaled by the spin speed, k ~ 1/speed), then the
table lays the spindle along s; s, at its equilibrium, stays. Mirror 1's tilt is
measured first (``3.p3-1``, no move); here mirror 2's (``3.p3m2-1``); one ``XLATE 3 a
b`` removes both; mirror 2's is measured again (translations along c2 until within the
threshold); the case is mounted back with mirror 1, shimmed and spun up with the spindle
at the equilibrium; mirror 1's tilt is measured again and translated out along c1 as the
mirror-1 step does. About 3 h of rotor time more (two brakings, two spin-ups).
"""

from __future__ import annotations

import math

import numpy as np

from procedures.esg import geometry as geo
from procedures.esg.acquisition import (
    Acquisition,
    EsgPlan,
    _move_head,
    _move_table,
    brake,
    spin_up_damped,
)
from procedures.esg.pickoff3 import (
    LEAVE_ARCSEC,
    PICKOFF,
    first_tilt,
    spindle_along,
    tilt_measurement,
)
from procedures.esg.remount import C1_IN_SPINDLE_FRAME, remount_and_shim
from procedures.runner import CheckSheetRun
from station.drivers.esg import EsgDrivers

PREFIX = "3.p3m2"


def equilibrium(plan: EsgPlan, acq: Acquisition, k_rps: float, rps: float) -> np.ndarray:
    """The drift equilibrium at spin speed ``rps``: step 3's k (measured at ``k_rps``)
    scaled by the speed (the unbalance drift is torque over angular momentum)."""
    return geo.drift_equilibrium(plan.latitude_deg, acq.unbalance_k_deg_hr * k_rps / rps)


def c1_onto(s_lab: np.ndarray) -> tuple[float, float]:
    """(table azimuth, spindle angle) with the table level, the spindle horizontal across
    s's vertical plane and c1 (mirror 2 mounted) along ``s_lab``."""
    az = ((geo.azimuth_deg(s_lab) - 90.0 + 180.0) % 360.0) - 180.0
    sc = geo.r_lc(az, 0.0, 0.0).T @ s_lab
    d = C1_IN_SPINDLE_FRAME
    gamma = math.degrees(math.atan2(sc[2], sc[1]) - math.atan2(d[2], d[1])) % 360.0
    return az, gamma


def _loop(st: EsgDrivers, plan: EsgPlan, sh: CheckSheetRun, name: str, axis: int,
          m: dict, along: tuple[float, float], first: tuple[float, float] | None = None
          ) -> dict:
    """Steps ``<name>-translate-k``: pickoff 3 moved along c1 (axis 0) or c2 (axis 1) by
    minus the tilt (``first``: the first move's both components), measured again, until
    within LEAVE_ARCSEC or ``alignment_iterations`` moves."""
    moved = 0
    while ((first is not None and moved == 0) or abs(m["tilt_arcsec"]) > LEAVE_ARCSEC) \
            and moved < plan.alignment_iterations:
        moved += 1
        with sh.step(f"{name}-translate-{moved}", "pickoff 3 translated by its tilt; "
                     "measured again") as s:
            move = [0.0, 0.0]
            move[axis] = -m["tilt_arcsec"]
            if first is not None and moved == 1:
                move = list(first)
            st.console.translate(PICKOFF, move[0], move[1])
            m = tilt_measurement(st, plan, along)
            s.reading = {"translation_arcsec": move, **m}
    return {"tilt_arcsec": m["tilt_arcsec"], "sigma_arcsec": m["sigma_arcsec"],
            "translations": moved}


def both_tilts(st: EsgDrivers, plan: EsgPlan, sh: CheckSheetRun, acq: Acquisition,
               m1: dict) -> dict:
    """Everything after ``3.p3-1`` (module doc), ``m1`` its measurement: the last
    measurements of both tilts and the translations made."""
    k_rps = st.console.speed()  # step 3's k holds at this speed
    with sh.step(f"{PREFIX}.brake", "rotor braked to rest") as s:
        brake(st, plan)
        s.reading = {"k_at_rps": k_rps, "spin_rps": st.console.speed()}
    remount_and_shim(st, plan, sh, 2, PREFIX)
    with sh.step(f"{PREFIX}.spin", "spin up with damping; at speed, table level and c1 "
                 "on step 3's drift equilibrium (k scaled by the speed); damped there; "
                 "damping off") as s:

        def c1_on_equilibrium() -> tuple[float, float]:
            az, gamma = c1_onto(equilibrium(plan, acq, k_rps, st.console.speed()))
            _move_table(st, plan, az=az, tilt=0.0)
            return az, _move_head(st, plan, gamma)

        az, gamma = spin_up_damped(st, plan, c1_on_equilibrium)
        # the spin axis sits where c1 is (within the damping's residual)
        s_lab = geo.r_lc(az, 0.0, gamma) @ C1_IN_SPINDLE_FRAME
        s.reading = {"settings_deg": [az, 0.0, gamma], "s_lab": s_lab.tolist(),
                     **st.console.status()}
    along = spindle_along(s_lab)
    with sh.step(f"{PREFIX}-1", "spindle along s, then reversed; pickoff 3 count ratio "
                 "over a spindle turn and back in each; half their means' difference = "
                 "pickoff 3's tilt towards mirror 2") as s:
        m2 = tilt_measurement(st, plan, along)
        s.reading = m2
    a, b = (-t if abs(t) > LEAVE_ARCSEC else 0.0
            for t in (m1["tilt_arcsec"], m2["tilt_arcsec"]))
    first = (a, b)
    out2 = _loop(st, plan, sh, PREFIX, 1, m2, along, first if any(first) else None)
    with sh.step(f"{PREFIX}.brake-2", "rotor braked to rest") as s:
        brake(st, plan)
        s.reading = {"spin_rps": st.console.speed()}
    acq.mount_coning_arcsec = remount_and_shim(st, plan, sh, 1, f"{PREFIX}.m1")
    with sh.step(f"{PREFIX}.respin", "spin up with damping; at speed, spindle on step 3's "
                 "drift equilibrium (k scaled by the speed); damped there; damping off") as s:

        def spindle_on_equilibrium() -> tuple[float, float]:
            acq.unbalance_k_deg_hr *= k_rps / st.console.speed()  # k at the present speed
            at = spindle_along(geo.drift_equilibrium(plan.latitude_deg,
                                                     acq.unbalance_k_deg_hr))
            _move_table(st, plan, az=at[0], tilt=at[1])
            _move_head(st, plan, 0.0)
            return at

        along1 = spin_up_damped(st, plan, spindle_on_equilibrium)
        s.reading = {"settings_deg": [along1[0], along1[1], 0.0],
                     "unbalance_k_deg_hr": acq.unbalance_k_deg_hr, **st.console.status()}
    if a == 0.0:
        out1 = {"tilt_arcsec": m1["tilt_arcsec"], "sigma_arcsec": m1["sigma_arcsec"],
                "translations": 0}
    else:
        with sh.step("3.p3-2", "mirror 1 along the spindle again: pickoff 3's tilt "
                     "towards mirror 1 measured again") as s:
            m = tilt_measurement(st, plan, along1)
            s.reading = m
        out1 = _loop(st, plan, sh, "3.p3", 0, m, along1)
    return {"mirror1": out1, "mirror2": out2}


def pickoff3_both(st: EsgDrivers, plan: EsgPlan, sh: CheckSheetRun, acq: Acquisition
                  ) -> dict:
    """Pickoff 3's tilts towards mirrors 1 and 2 measured and translated out after step 3
    (module doc; ``3.p3-1`` as procedures.esg.pickoff3 measures it)."""
    return both_tilts(st, plan, sh, acq, first_tilt(st, plan, sh, acq))
