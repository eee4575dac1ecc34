"""Ground truth of the simulated ESG laboratory that a calibration can be judged by."""

from __future__ import annotations

import math

import numpy as np

from sim.esg.world import EsgWorld


def true_pickoff1_coning_arcsec(world: EsgWorld) -> float:
    """Angle between pickoff 1 and the spindle axis in the case (what ESG-PA measures)."""
    u = world.case.mounting.T @ np.array([1.0, 0.0, 0.0])
    p1 = world.case.pickoffs[0]
    return math.degrees(math.acos(min(1.0, float(p1 @ u) / float(np.linalg.norm(p1))))) * 3600
