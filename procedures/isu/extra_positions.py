"""Extra accelerometer positions beyond the manual (issue 19, our design): after Chart
II-14, static positions set as positions 7-15 (II-5's scheme: phi1 = 0, phi2 = 90, level
corrections) but with each accelerometer's input axis tilted from vertical by the options'
angles, both signs, so that the odd part of Chart IV-1 separates D1 and D3 at several input
levels, as the bisector positions 13, 14 (Chart II-14) do at one.
"""

from __future__ import annotations

import math

import numpy as np

SET_S = 25.0  # setting the table with level corrections, about (a default day's positions)
E3 = np.eye(3)


def tilted_ups(tilts_deg: list[float] | tuple[float, ...]) -> list[np.ndarray]:
    """Body vectors put up: per tilt theta and accelerometer k, +-(cos theta B_k + sin theta
    B_k+1) (k + 1 cyclic): accelerometer k at cos theta, k + 1 at sin theta (of g)."""
    out = []
    for th in tilts_deg:
        c, s = math.cos(math.radians(th)), math.sin(math.radians(th))
        for k in range(3):
            u = c * E3[k] + s * E3[(k + 1) % 3]
            out += [u, -u]
    return out


def gate_of(a_up: float, vertical_s: float, horizontal_s: float) -> float:
    """An accelerometer's gate at a tilted position: the plan's vertical gate when its input
    axis is nearer vertical than horizontal (|A.up| > cos 45 deg), else the horizontal gate
    (the manual counts the bisector positions 13, 14 with the horizontal gate, II-6.2)."""
    return vertical_s if abs(a_up) > math.sqrt(0.5) + 1e-9 else horizontal_s
