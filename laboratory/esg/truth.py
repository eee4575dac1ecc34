"""Ground truth of the simulated ESG laboratory that a calibration can be judged by."""

from __future__ import annotations

import math

import numpy as np

from sim.esg.world import EsgWorld


def _angle_arcsec(a: np.ndarray, b: np.ndarray) -> float:
    c = float(a @ b) / float(np.linalg.norm(a) * np.linalg.norm(b))
    return math.degrees(math.acos(min(1.0, c))) * 3600


def true_pickoff_coning_arcsec(world: EsgWorld, pickoff: int, t: float) -> float:
    """Angle between a pickoff and the spindle axis in the case at time t, whichever
    mirror is mounted along the spindle then (what a coning turn at t measures)."""
    u = world.mount.mounting_at(t).T @ np.array([1.0, 0.0, 0.0])
    return _angle_arcsec(world.case.pickoffs_at(t)[pickoff - 1], u)


def true_pickoff_mirror_arcsec(world: EsgWorld, pickoff: int, t: float | None = None
                               ) -> float:
    """Angle between pickoff 1 or 2 and its reference mirror's normal at time t (default
    now): the alignment the report's procedure aims at, whatever the mounting."""
    p = world.case.pickoffs if t is None else world.case.pickoffs_at(t)
    return _angle_arcsec(p[pickoff - 1], world.case.mirror(pickoff))


def true_pickoff1_coning_arcsec(world: EsgWorld) -> float:
    """Angle between pickoff 1 and the spindle axis in the case (what ESG-PA measures)."""
    u = world.case.mounting.T @ np.array([1.0, 0.0, 0.0])
    p1 = world.case.pickoffs[0]
    return math.degrees(math.acos(min(1.0, float(p1 @ u) / float(np.linalg.norm(p1))))) * 3600


def true_pickoff3_tilts_arcsec(world: EsgWorld, t: float | None = None
                               ) -> tuple[float, float, float]:
    """Pickoff 3 at time t (default now): its tilt towards mirror 1, towards mirror 2
    and its angle from its nominal line m1 x m2 (arcsec)."""
    p = world.case.pickoffs if t is None else world.case.pickoffs_at(t)
    p3 = p[2] / float(np.linalg.norm(p[2]))
    m1, m2 = world.case.mirror(1), world.case.mirror(2)
    n3 = np.cross(m1, m2)
    return (math.degrees(math.asin(float(p3 @ m1))) * 3600.0,
            math.degrees(math.asin(float(p3 @ m2))) * 3600.0,
            _angle_arcsec(p3, n3 / float(np.linalg.norm(n3))))


def true_pickoff3_spindle_tilt_arcsec(world: EsgWorld, t: float) -> float:
    """Pickoff 3's tilt towards the spindle axis in the case at time t (what the turn of
    procedures.esg.pickoff3 measures: mirror 1 within its shim residual)."""
    u = world.mount.mounting_at(t).T @ np.array([1.0, 0.0, 0.0])
    p3 = world.case.pickoffs_at(t)[2]
    return math.degrees(math.asin(float(p3 @ u) / float(np.linalg.norm(p3)))) * 3600.0
