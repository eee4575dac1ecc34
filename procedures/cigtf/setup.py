"""The pre-test set-up of the CIGTF fixture (report 001, section 4.1, first paragraph).

"The vertical test fixture axis is aligned parallel to the local gravity vector by means of
bubble levels ... the horizontal axis is aligned parallel to the horizontal component of
earth rotation rate by optical means. Digital displays ... should both register zero."
As steps: the bubble levels are read at vertical 0 and 180 deg, whose half-difference is
the axis's tilt (b from the EW level, -c from the NS level; the levels' zero offsets
cancel), the levelling screws take it out, and the round is repeated until both tilts are
within the tolerance ("less than 1 sec", Appendix II); the same for the horizontal axis's
azimuth a + d, read by the autocollimator at horizontal 0 and 180 deg (the half-sum: the
mirror's error cancels) and taken out by the base azimuth adjustment; then the displays
must read 0 0. What the set-up leaves (its last round's estimates and their sigmas, from
the readings' own scatter) is the record's b, c and a + d.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from procedures.runner import Run
from station.drivers.cigtf import CigtfDrivers
from station.errors import CheckFailed


@dataclass(frozen=True)
class SetupPlan:
    readings: int = 10  # readings of each instrument at each position (18 dof per sigma)
    tolerance_arcsec: float = 0.5  # levelled and aligned "less than 1 sec" (Appendix II)
    max_rounds: int = 8  # adjusting rounds, before the confirming one
    resolution_arcsec: float = 0.1  # of the levels and the autocollimator (their reply)
    # the fixture's repeatability (0.2 arcsec at 3 sigma): each arrival at vertical 0
    # turns the horizontal axis's azimuth by that much
    repeatability_sd_arcsec: float = 0.2 / 3.0
    move_timeout_s: float = 120.0


@dataclass(frozen=True)
class Estimate:
    """One round's estimate from readings at two positions, arcsec."""

    value: float
    sigma: float
    at_0: float
    at_180: float


def _pair(r0: list[float], r180: list[float], sign: float, plan: SetupPlan,
          extra_var: float = 0.0) -> Estimate:
    """(mean0 + sign * mean180) / 2 and its sigma: the pooled scatter of one reading
    (at least the resolution's, step^2 / 12) over the readings, and ``extra_var``."""
    a, b = np.asarray(r0, float), np.asarray(r180, float)
    var = max((a.var(ddof=1) + b.var(ddof=1)) / 2.0, plan.resolution_arcsec**2 / 12.0)
    sd = math.sqrt(var * (1.0 / a.size + 1.0 / b.size) / 4.0 + extra_var)
    return Estimate((a.mean() + sign * b.mean()) / 2.0, sd, float(a.mean()), float(b.mean()))


def _at(st: CigtfDrivers, plan: SetupPlan, axis: str, deg: int,
        read: Callable[[], float | tuple[float, float]]) -> list:
    st.fixture.move(axis, deg)
    st.fixture.wait_hold(plan.move_timeout_s)
    return [read() for _ in range(plan.readings)]


def level(st: CigtfDrivers, plan: SetupPlan) -> dict:
    """Rounds of level readings at vertical 0 and 180 deg and screw adjustments."""
    rounds: list[dict] = []
    st.fixture.move("H", 0)
    within = False
    for _ in range(plan.max_rounds + 1):
        r0 = _at(st, plan, "V", 0, st.aids.levels)
        r180 = _at(st, plan, "V", 180, st.aids.levels)
        ew = _pair([x[0] for x in r0], [x[0] for x in r180], -1.0, plan)
        ns = _pair([x[1] for x in r0], [x[1] for x in r180], -1.0, plan)
        rnd: dict = {"ew_arcsec": ew.value, "ns_arcsec": ns.value, "ew_sigma_arcsec": ew.sigma,
               "ns_sigma_arcsec": ns.sigma, "ew_offset_arcsec": (ew.at_0 + ew.at_180) / 2,
               "ns_offset_arcsec": (ns.at_0 + ns.at_180) / 2}
        adjusted: list[str] = []
        rnd["adjusted"], rnd["confirming"] = adjusted, within
        rounds.append(rnd)
        st.fixture.move("V", 0)
        st.fixture.wait_hold(plan.move_timeout_s)
        if within:  # the confirming round: what the set-up leaves
            return {"b_arcsec": ew.value, "b_sigma_arcsec": ew.sigma,
                    "c_arcsec": -ns.value, "c_sigma_arcsec": ns.sigma, "rounds": rounds}
        if max(abs(ew.value), abs(ns.value)) <= plan.tolerance_arcsec:
            within = True
            continue
        for name, est in (("EW", ew), ("NS", ns)):
            if abs(est.value) > plan.tolerance_arcsec:
                st.aids.tilt(name, max(-600.0, min(600.0, -est.value)))
                adjusted.append(name)
    raise CheckFailed(f"vertical axis not levelled within {plan.tolerance_arcsec:g} arcsec "
                      f"after {plan.max_rounds} rounds (last EW {rounds[-1]['ew_arcsec']:+.2f}"
                      f", NS {rounds[-1]['ns_arcsec']:+.2f} arcsec)")


def align_north(st: CigtfDrivers, plan: SetupPlan) -> dict:
    """Rounds of autocollimator readings at horizontal 0 and 180 deg (vertical 0) and base
    azimuth adjustments."""
    rounds: list[dict] = []
    st.fixture.move("V", 0)
    extra = plan.repeatability_sd_arcsec**2 / 2.0  # two arrivals at vertical 0, averaged
    within = False
    for _ in range(plan.max_rounds + 1):
        r0 = _at(st, plan, "H", 0, st.aids.azimuth)
        r180 = _at(st, plan, "H", 180, st.aids.azimuth)
        az = _pair(r0, r180, 1.0, plan, extra)
        rounds.append({"azimuth_arcsec": az.value, "sigma_arcsec": az.sigma,
                       "mirror_arcsec": (az.at_0 - az.at_180) / 2, "adjusted": False,
                       "confirming": within})
        st.fixture.move("H", 0)
        st.fixture.wait_hold(plan.move_timeout_s)
        if within:  # the confirming round: what the set-up leaves
            return {"north_arcsec": az.value, "north_sigma_arcsec": az.sigma,
                    "rounds": rounds}
        if abs(az.value) <= plan.tolerance_arcsec:
            within = True
            continue
        st.aids.turn_base(max(-3600.0, min(3600.0, -az.value)))
        rounds[-1]["adjusted"] = True
    raise CheckFailed(f"horizontal axis not aligned north within {plan.tolerance_arcsec:g} "
                      f"arcsec after {plan.max_rounds} rounds (last "
                      f"{rounds[-1]['azimuth_arcsec']:+.2f} arcsec)")


def pretest_setup(st: CigtfDrivers, run: Run, plan: SetupPlan | None = None) -> dict:
    """Section 4.1's set-up as check-sheet 4.1-S; the residual b, c (levels) and a + d
    (``north_arcsec``, the horizontal axis's azimuth) with their sigmas, arcsec."""
    plan = plan or SetupPlan()
    with run.sheet("4.1-S", "Pre-test set-up") as sh:
        with sh.step("4.1.S1", "level the vertical axis: bubble levels read at vertical 0 and "
                     "180 deg (half-difference: the tilt), levelling screws, repeated until "
                     f"both within {plan.tolerance_arcsec:g} arcsec") as s:
            lv = level(st, plan)
            s.reading = lv
        with sh.step("4.1.S2", "align the horizontal axis north: autocollimator read at "
                     "horizontal 0 and 180 deg (half-sum: the azimuth), base azimuth "
                     f"adjustment, repeated until within {plan.tolerance_arcsec:g} arcsec") as s:
            nz = align_north(st, plan)
            s.reading = nz
        with sh.step("4.1.S3", "both axis displays read 0 0") as s:
            st.fixture.move("V", 0)
            st.fixture.wait_hold(plan.move_timeout_s)
            st.fixture.move("H", 0)
            st.fixture.wait_hold(plan.move_timeout_s)
            pos = st.fixture.position()
            s.reading = {"vertical_deg": pos[0], "horizontal_deg": pos[1]}
            if pos != (0, 0):
                raise CheckFailed(f"axis displays read {pos[0]} {pos[1]}, not 0 0")
    return {k: v for k, v in {**lv, **nz}.items() if k != "rounds"} | {
        "level_rounds": len(lv["rounds"]), "azimuth_rounds": len(nz["rounds"])}
