"""The laboratory's nominal mounting geometry for the ESG on the dividing head (report 004).

What the engineer knows without the gyro: the turntable azimuth A, the tilt E and the
spindle angle gamma place the case; mirror 1 (pickoff 1) lies along the spindle, and at
A = E = gamma = 0 the case axes are c1 north, c2 up, c3 east (docs/esg.md). From that
the procedure computes where to put the axes so the spin axis takes a wanted direction in
the case, e.g. the equal-count-ratio direction of step 4 or the spindle-perpendicular
setting of step 5. Lab frame: x east, y north, z up. Angles in degrees at the interface.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

EARTH_RATE_DEG_HR = 15.04107  # sidereal rate


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# case axes at A = E = gamma = 0 as columns in the lab: c1 north, c2 up, c3 east
R0 = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def r_lc(azimuth_deg: float, tilt_deg: float, gamma_deg: float) -> np.ndarray:
    """Case-to-lab rotation: Rz(-A) Rx(E) R0 Rx_c1(gamma)."""
    return (_rz(-math.radians(azimuth_deg)) @ _rx(math.radians(tilt_deg)) @ R0
            @ _rx(math.radians(gamma_deg)))


def unit(v: ArrayLike) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def elevation_deg(v: ArrayLike) -> float:
    v = unit(v)
    return math.degrees(math.asin(max(-1.0, min(1.0, v[2]))))


def azimuth_deg(v: ArrayLike) -> float:
    v = unit(v)
    return math.degrees(math.atan2(v[0], v[1]))


def from_az_el(az_deg: float, el_deg: float) -> np.ndarray:
    a, e = math.radians(az_deg), math.radians(el_deg)
    return np.array([math.sin(a) * math.cos(e), math.cos(a) * math.cos(e), math.sin(e)])


def polar_axis(latitude_deg: float) -> np.ndarray:
    """The Earth's polar axis (EPA) in the lab."""
    return from_az_el(0.0, latitude_deg)


def point_case(d_case: ArrayLike, s_lab: ArrayLike,
               tilt_limit_deg: float = 90.0) -> tuple[float, float, float]:
    """(A, E, gamma) that put the case direction ``d_case`` on the lab direction ``s_lab``.

    The spindle (c1) goes in the vertical plane of s at the angle acos(d1) from s, on
    whichever side keeps the tilt inside the limit (turning the table by 180 deg if it
    must); the spindle angle then turns d's component across the spindle onto s's.
    """
    d, s = unit(d_case), unit(s_lab)
    ang = math.degrees(math.acos(max(-1.0, min(1.0, d[0]))))
    az_s, el_s = azimuth_deg(s), elevation_deg(s)
    best = None
    for el_u in (el_s - ang, el_s + ang):
        # an elevation beyond +-90 deg is the same line seen from the other azimuth
        az_u, e = az_s, el_u
        if e > 90.0:
            az_u, e = az_s + 180.0, 180.0 - e
        elif e < -90.0:
            az_u, e = az_s + 180.0, -180.0 - e
        if abs(e) <= tilt_limit_deg and (best is None or abs(e) < abs(best[1])):
            best = (((az_u + 180.0) % 360.0) - 180.0, e)
    if best is None:
        raise ValueError(f"no tilt within +-{tilt_limit_deg:g} deg puts the case on s")
    a, e = best
    sc = r_lc(a, e, 0.0).T @ s  # s in case axes at gamma = 0
    gamma = math.degrees(math.atan2(sc[2], sc[1]) - math.atan2(d[2], d[1]))
    return a, e, ((gamma + 180.0) % 360.0) - 180.0


def drift_equilibrium(latitude_deg: float, k_deg_hr: float) -> np.ndarray:
    """Where axial-unbalance drift k (s x down) and Earth rate cancel: unit(Omega + k down).

    In the Earth-fixed lab ds/dt = s x (k down + Omega), so s is steady along that vector;
    it lies in the north-south vertical plane, offset from the polar axis (procedure step 3).
    """
    lat = math.radians(latitude_deg)
    w = EARTH_RATE_DEG_HR * np.array([0.0, math.cos(lat), math.sin(lat)])
    return unit(w + k_deg_hr * np.array([0.0, 0.0, -1.0]))


def unbalance_k_from_east_drift(east_rate_deg_hr: float, s_lab: ArrayLike) -> float:
    """k (deg/hr) from an east-west drift rate seen with s in the meridian plane.

    For s = (0, cos e, sin e): s x (k down) = (-k cos e, 0, 0), so the east rate is
    -k cos e (Earth rate adds nothing out of the plane when s is at equilibrium already,
    and exactly nothing when s is on the polar axis).
    """
    return -east_rate_deg_hr / math.cos(math.radians(elevation_deg(s_lab)))
