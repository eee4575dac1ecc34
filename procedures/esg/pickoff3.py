"""Pickoff 3's tilt towards mirror 1, measured and translated out (report 004, "Mirror and
Pickoff Alignment": pickoff 3 set perpendicular to the plane of the two mirror normals by
the coning measurement "modified slightly"; issue 20). Our design, run with
``remount_alignment`` after step 7 (docs/esg-options.md):

With mirror 1 along the spindle and the spin axis s along the spindle, pickoff 3 is
across both and its colatitude is 90 deg less its tilt towards the spindle (mirror 1).
After step 3 s stays at the drift equilibrium, where step 3 laid the spindle; after step 7
the equator's count ratio is known. So the spindle is laid there again and turned through
one turn and back (a palindrome: a steady drift of s cancels in the mean); the mean of
pickoff 3's count ratio against the equator's, over the drawing's slope at the equator,
is the tilt (s's own offset from the spindle is the turn's first harmonic and drops out).
``XLATE 3 -tilt 0`` (along c1) removes it; the turn is read again. The tilt towards mirror
2 is not measured here: it needs s along the spindle with mirror 2 mounted, which no
stationary set-up of ours gives (docs/esg-options.md).
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
    _read,
    _settings,
    plan_slope_per_deg,
)
from procedures.runner import CheckSheetRun
from station.drivers.esg import EsgDrivers
from station.errors import CheckFailed

PICKOFF = 3
# a measured tilt below this is left alone (our choice: the fixture's own error is 1 arcsec
# plus 5 %, and the turn's noise about 1 arcsec)
LEAVE_ARCSEC = 3.0


def palindrome(positions: int) -> list[float]:
    """Spindle angles of one turn and back: 0, 360/n, ..., 360, ..., 360/n, 0."""
    out = [360.0 * k / positions for k in range(positions + 1)]
    return out + out[-2::-1]


def mean_ratio(spindle_deg: list[float], t_s: list[float], cr: list[float]
               ) -> tuple[float, float]:
    """(mean, its sigma) of a count ratio over a turn, with the first harmonic of the
    spindle angle and a linear drift in time fitted alongside."""
    t0 = 0.5 * (t_s[0] + t_s[-1])
    a = np.array([[1.0, math.cos(math.radians(g)), math.sin(math.radians(g)), t - t0]
                  for g, t in zip(spindle_deg, t_s, strict=True)])
    y = np.asarray(cr, float)
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    res = y - a @ coef
    cov = float(res @ res) / max(1, len(y) - 4) * np.linalg.inv(a.T @ a)
    return float(coef[0]), math.sqrt(float(cov[0, 0]))


def tilt_turn(st: EsgDrivers, plan: EsgPlan, acq: Acquisition) -> dict:
    """One palindromic spindle turn reading pickoff 3 with s along the spindle: its tilt
    towards the spindle (mirror 1), arcsec, and the sigma of the turn's mean."""
    slope = plan_slope_per_deg(90.0, plan)
    g_list, t_list, cr_list = [], [], []
    for g in palindrome(plan.coning_positions):
        gr = _move_head(st, plan, g)
        r = _read(st, plan, (PICKOFF, 2))
        cr = r.cr[PICKOFF]
        if cr is None:
            raise CheckFailed("pickoff 3 off the pattern with s along the spindle")
        g_list.append(gr)
        t_list.append(r.t_s)
        cr_list.append(float(cr))
    mean, sigma = mean_ratio(g_list, t_list, cr_list)
    # colatitude = 90 deg - tilt, and CR - cr_eq = slope * (colatitude - 90 deg)
    tilt = -(mean - acq.cr_eq) / slope * 3600.0
    return {"spindle_deg": g_list, "t_s": t_list, "cr_pickoff3": cr_list,
            "cr_mean": mean, "cr_eq": acq.cr_eq, "tilt_arcsec": tilt,
            "sigma_arcsec": sigma / abs(slope) * 3600.0}


def pickoff3_alignment(st: EsgDrivers, plan: EsgPlan, sh: CheckSheetRun,
                       acq: Acquisition) -> dict:
    """Steps ``7.p3-1``, ``7.p3-translate-k`` and ``7.p3-back`` (module doc); the last
    turn's tilt and the number of translations."""
    az, tilt, gamma = _settings(st)
    s_lab = geo.drift_equilibrium(plan.latitude_deg, acq.unbalance_k_deg_hr)
    with sh.step("7.p3-1", "spindle along s (step 3's equilibrium); pickoff 3 count ratio "
                 "over one spindle turn and back; its mean against the equator's = "
                 "pickoff 3's tilt towards mirror 1") as s:
        _move_table(st, plan, az=0.0, tilt=geo.elevation_deg(s_lab))
        turn = tilt_turn(st, plan, acq)
        s.reading = turn
    moved = 0
    while abs(turn["tilt_arcsec"]) > LEAVE_ARCSEC and moved < plan.alignment_iterations:
        moved += 1
        with sh.step(f"7.p3-translate-{moved}", "pickoff 3 translated along c1 by its "
                     "tilt; the turn read again") as s:
            a = -turn["tilt_arcsec"]
            st.console.translate(PICKOFF, a, 0.0)
            turn = tilt_turn(st, plan, acq)
            s.reading = {"translation_arcsec": [a, 0.0], **turn}
    with sh.step("7.p3-back", "table and spindle back to step 7's settings") as s:
        _move_table(st, plan, az=az, tilt=tilt)
        _move_head(st, plan, gamma)
        s.reading = {"settings_deg": list(_settings(st))}
    return {"tilt_arcsec": turn["tilt_arcsec"], "sigma_arcsec": turn["sigma_arcsec"],
            "translations": moved}
