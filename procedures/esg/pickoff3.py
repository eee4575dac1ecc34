"""Pickoff 3's tilt towards mirror 1, measured and translated out (report 004, "Mirror and
Pickoff Alignment": pickoff 3 set perpendicular to the plane of the two mirror normals by
the coning measurement "modified slightly"; issue 20). Our design, run with
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
2 is not measured here: it needs s along the spindle with mirror 2 mounted, which no
stationary set-up of ours gives (docs/esg-options.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable

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


def mean_ratio(spindle_deg: list[float], t_s: list[float], cr: list[float],
               curved: bool = False) -> tuple[float, float]:
    """(mean, its sigma) of a count ratio over a turn, with the first harmonic of the
    spindle angle and a linear drift in time fitted alongside; ``curved``: also a first
    harmonic growing with the square of the time from the turn's middle (s leaving the
    spindle along a curve while the table follows it)."""
    t0 = 0.5 * (t_s[0] + t_s[-1])
    rows = []
    for g, t in zip(spindle_deg, t_s, strict=True):
        c, sn = math.cos(math.radians(g)), math.sin(math.radians(g))
        q = ((t - t0) / 600.0) ** 2
        rows.append([1.0, c, sn, t - t0] + ([q * c, q * sn] if curved else []))
    a = np.array(rows)
    y = np.asarray(cr, float)
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    res = y - a @ coef
    cov = float(res @ res) / max(1, len(y) - a.shape[1]) * np.linalg.inv(a.T @ a)
    return float(coef[0]), math.sqrt(float(cov[0, 0]))


Pointing = Callable[[float], tuple[float, float]]  # time -> table (azimuth, tilt) along s


def mean_turn(st: EsgDrivers, plan: EsgPlan, pointing: Pointing | None = None,
              reverse: bool = False) -> dict:
    """One palindromic spindle turn reading pickoff 3: its count ratios and their mean
    (first harmonic and drift fitted out) with its sigma. With ``pointing`` the table is
    laid along s (or against it, ``reverse``) again before each reading."""
    g_list, t_list, cr_list = [], [], []
    for g in palindrome(plan.coning_positions):
        if pointing is not None:
            _lay(st, plan, pointing(st.clock.now()), reverse)
        gr = _move_head(st, plan, g)
        r = _read(st, plan, (PICKOFF, 2))
        cr = r.cr[PICKOFF]
        if cr is None:
            raise CheckFailed("pickoff 3 off the pattern with s along the spindle")
        g_list.append(gr)
        t_list.append(r.t_s)
        cr_list.append(float(cr))
    mean, sigma = mean_ratio(g_list, t_list, cr_list, curved=pointing is not None)
    return {"spindle_deg": g_list, "t_s": t_list, "cr_pickoff3": cr_list,
            "cr_mean": mean, "cr_sigma": sigma}


def _lay(st: EsgDrivers, plan: EsgPlan, along: tuple[float, float], reverse: bool) -> None:
    """The spindle along (azimuth, tilt), or reversed: table turned 180 deg, tilt negated."""
    az, tilt = (along[0] + 180.0, -along[1]) if reverse else along
    _move_table(st, plan, az=((az + 180.0) % 360.0) - 180.0, tilt=tilt)


def tilt_measurement(st: EsgDrivers, plan: EsgPlan, along: tuple[float, float],
                     pointing: Pointing | None = None) -> dict:
    """Pickoff 3's tilt towards the spindle (the mirror along it), arcsec, with its
    sigma: a turn with the spindle along s (table at ``along``: azimuth, tilt; or following
    ``pointing``) and one with it reversed (colatitudes 90 - tilt and 90 + tilt; the
    equator's ratio cancels)."""
    slope = plan_slope_per_deg(90.0, plan)
    turns = []
    for reverse in (False, True):
        _lay(st, plan, along if pointing is None else pointing(st.clock.now()), reverse)
        turns.append(mean_turn(st, plan, pointing, reverse))
    plus, minus = turns
    # CR - CR_eq = slope * (colatitude - 90): plus - minus = -2 slope tilt
    d = plus["cr_mean"] - minus["cr_mean"]
    return {"along": plus, "reversed": minus,
            "tilt_arcsec": -d / (2.0 * slope) * 3600.0,
            "sigma_arcsec": math.hypot(plus["cr_sigma"], minus["cr_sigma"])
            / (2.0 * abs(slope)) * 3600.0}


def earth_pointing(latitude_deg: float, s0_lab: np.ndarray, t0: float) -> Pointing:
    """Table angles along a free spin axis that was at ``s0_lab`` at ``t0``, moved by the
    Earth's rate alone (ds/dt = s x Omega; unbalance drift not modelled: s near vertical
    feels little of it)."""
    w = geo.polar_axis(latitude_deg)
    rate = math.radians(geo.EARTH_RATE_DEG_HR) / 3600.0

    def at(t: float) -> tuple[float, float]:
        phi = -rate * (t - t0)  # rotation about Omega by -|Omega| t
        s = (s0_lab * math.cos(phi) + np.cross(w, s0_lab) * math.sin(phi)
             + w * float(w @ s0_lab) * (1.0 - math.cos(phi)))
        return geo.azimuth_deg(s), geo.elevation_deg(s)
    return at


def mirror2_tilt(st: EsgDrivers, plan: EsgPlan, sh: CheckSheetRun, s0_lab: np.ndarray,
                 t0: float) -> dict:
    """Steps ``PA2.p3-1``, ``PA2.p3-translate-k`` (mirror 2 along the spindle, the rotor
    free since ``t0`` with s at ``s0_lab``): pickoff 3's tilt towards mirror 2 measured
    with the table following s and translated out along c2 (module doc)."""
    pointing = earth_pointing(plan.latitude_deg, s0_lab, t0)
    return _adjust(st, plan, sh, "PA2.p3", 1, "mirror 2", "c2",
                   lambda: tilt_measurement(st, plan, pointing(st.clock.now()), pointing))


def _adjust(st: EsgDrivers, plan: EsgPlan, sh: CheckSheetRun, prefix: str, axis: int,
            mirror: str, along: str, measure: Callable[[], dict]) -> dict:
    """The measurement, then translations along case axis c1 (axis 0) or c2 (axis 1) until
    the tilt is within LEAVE_ARCSEC (at most alignment_iterations)."""
    with sh.step(f"{prefix}-1", "spindle along s, then reversed; pickoff 3 count ratio "
                 "over a spindle turn and back in each; half their means' difference = "
                 f"pickoff 3's tilt towards {mirror}") as s:
        m = measure()
        s.reading = m
    moved = 0
    while abs(m["tilt_arcsec"]) > LEAVE_ARCSEC and moved < plan.alignment_iterations:
        moved += 1
        with sh.step(f"{prefix}-translate-{moved}", f"pickoff 3 translated along {along} "
                     "by its tilt; measured again") as s:
            move = [0.0, 0.0]
            move[axis] = -m["tilt_arcsec"]
            st.console.translate(PICKOFF, move[0], move[1])
            m = measure()
            s.reading = {"translation_arcsec": move, **m}
    return {"tilt_arcsec": m["tilt_arcsec"], "sigma_arcsec": m["sigma_arcsec"],
            "translations": moved}


def pickoff3_alignment(st: EsgDrivers, plan: EsgPlan, sh: CheckSheetRun,
                       acq: Acquisition) -> dict:
    """Steps ``3.p3-1`` and ``3.p3-translate-k`` (module doc): pickoff 3's tilt towards
    mirror 1 with s at step 3's equilibrium, translated out along c1."""
    s_lab = geo.drift_equilibrium(plan.latitude_deg, acq.unbalance_k_deg_hr)
    along = (geo.azimuth_deg(s_lab), geo.elevation_deg(s_lab))
    return _adjust(st, plan, sh, "3.p3", 0, "mirror 1", "c1",
                   lambda: tilt_measurement(st, plan, along))
