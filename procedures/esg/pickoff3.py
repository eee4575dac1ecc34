"""Pickoff 3's tilt towards mirror 1, measured and translated out (report 004, "Mirror and
Pickoff Alignment": pickoff 3 set perpendicular to the plane of the two mirror normals by
an adapted coning measurement it does not spell out; issue 20). Our design, run with
``remount_alignment`` after step 3 (docs/esg-options.md):

With mirror 1 along the spindle and the spin axis s along the spindle, pickoff 3 is
across both and its colatitude is 90 deg less its tilt towards the spindle (mirror 1);
with the spindle reversed (table turned 180 deg, tilt negated) it is 90 deg plus the tilt.
After step 3 s stays at the drift equilibrium where step 3 laid the spindle. In each
direction the spindle is turned through one turn and back (a palindrome: a steady drift
of s cancels in the mean; s's own offset from the spindle is the turn's first harmonic);
half the difference of the two mean count ratios over the drawing's slope at the equator
is the tilt, with no need of the equator's ratio (step 7's, measured with pickoff 2, was
off by up to 7 arcsec in our trials). ``XLATE 3 -tilt 0`` (along c1) removes it; the tilt
is measured again. The tilt towards mirror
2 needs s along the spindle with mirror 2 mounted: procedures.esg.pickoff3_mirror2 does it
in a second remount, with ``pickoff3_mirror2``.
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


def mean_turn(st: EsgDrivers, plan: EsgPlan) -> dict:
    """One palindromic spindle turn reading pickoff 3: its count ratios and their mean
    (first harmonic and drift fitted out) with its sigma."""
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
    return {"spindle_deg": g_list, "t_s": t_list, "cr_pickoff3": cr_list,
            "cr_mean": mean, "cr_sigma": sigma}


def tilt_measurement(st: EsgDrivers, plan: EsgPlan, along: tuple[float, float]) -> dict:
    """Pickoff 3's tilt towards the spindle (mirror 1), arcsec, with its sigma: a turn
    with the spindle along s (table at ``along``: azimuth, tilt) and one with it
    reversed (colatitudes 90 - tilt and 90 + tilt; the equator's ratio cancels)."""
    slope = plan_slope_per_deg(90.0, plan)
    az, tilt = along
    turns = []
    for a, e in ((az, tilt), (az + 180.0, -tilt)):
        _move_table(st, plan, az=((a + 180.0) % 360.0) - 180.0, tilt=e)
        turns.append(mean_turn(st, plan))
    plus, minus = turns
    # CR - CR_eq = slope * (colatitude - 90): plus - minus = -2 slope tilt
    d = plus["cr_mean"] - minus["cr_mean"]
    return {"along": plus, "reversed": minus,
            "tilt_arcsec": -d / (2.0 * slope) * 3600.0,
            "sigma_arcsec": math.hypot(plus["cr_sigma"], minus["cr_sigma"])
            / (2.0 * abs(slope)) * 3600.0}


def first_tilt(st: EsgDrivers, plan: EsgPlan, sh: CheckSheetRun, acq: Acquisition
               ) -> dict:
    """Step ``3.p3-1``: the tilt towards mirror 1 with s at step 3's equilibrium."""
    with sh.step("3.p3-1", "spindle along s (step 3's equilibrium), then reversed; pickoff "
                 "3 count ratio over a spindle turn and back in each; half their means' "
                 "difference = pickoff 3's tilt towards mirror 1") as s:
        m = tilt_measurement(st, plan, step3_along(plan, acq))
        s.reading = m
    return m


def step3_along(plan: EsgPlan, acq: Acquisition) -> tuple[float, float]:
    """Table (azimuth, tilt) along step 3's drift equilibrium."""
    return spindle_along(geo.drift_equilibrium(plan.latitude_deg, acq.unbalance_k_deg_hr))


def spindle_along(s_lab: np.ndarray) -> tuple[float, float]:
    """Table (azimuth, tilt) with the spindle along ``s_lab``."""
    return geo.azimuth_deg(s_lab), geo.elevation_deg(s_lab)


def pickoff3_alignment(st: EsgDrivers, plan: EsgPlan, sh: CheckSheetRun,
                       acq: Acquisition) -> dict:
    """Steps ``3.p3-1`` and ``3.p3-translate-k`` (module doc); the last measurement's
    tilt and the number of translations."""
    along = step3_along(plan, acq)
    m = first_tilt(st, plan, sh, acq)
    moved = 0
    while abs(m["tilt_arcsec"]) > LEAVE_ARCSEC and moved < plan.alignment_iterations:
        moved += 1
        with sh.step(f"3.p3-translate-{moved}", "pickoff 3 translated along c1 by its "
                     "tilt; measured again") as s:
            a = -m["tilt_arcsec"]
            st.console.translate(PICKOFF, a, 0.0)
            m = tilt_measurement(st, plan, along)
            s.reading = {"translation_arcsec": [a, 0.0], **m}
    return {"tilt_arcsec": m["tilt_arcsec"], "sigma_arcsec": m["sigma_arcsec"],
            "translations": moved}
