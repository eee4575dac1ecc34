"""Gyrocompassing scale factor (report 001, eqs. 7 and 9-14) at any site latitude."""

from __future__ import annotations

import math

ARCSEC_PER_RAD = 180.0 * 3600.0 / math.pi  # 206264.806
EARTH_RATE_DEG_PER_SIDEREAL_HR = 15.0  # one turn per sidereal day
REPORT_HORIZONTAL_RATE = 12.59562  # deg/sidereal hr at the report's site (eq. 7 text)
REPORT_LATITUDE_DEG = math.degrees(math.acos(REPORT_HORIZONTAL_RATE / 15.0))  # 32.8907


def horizontal_earth_rate(latitude_deg: float) -> float:
    """Horizontal Earth rate omega_E cos(lambda) in deg/sidereal hr."""
    return EARTH_RATE_DEG_PER_SIDEREAL_HR * math.cos(math.radians(latitude_deg))


def gsf_constant(latitude_deg: float = REPORT_LATITUDE_DEG) -> float:
    """The eq. 7 constant arcsec/(4 omega_EH) per deg/hr: 4093.979 at the report's site."""
    return ARCSEC_PER_RAD / (4.0 * horizontal_earth_rate(latitude_deg))


def gsf_from_scale_factor(s_t: float, latitude_deg: float = REPORT_LATITUDE_DEG) -> float:
    """GSF in arcsec per current unit from the torquer scale factor S_T (deg/hr per unit)."""
    return gsf_constant(latitude_deg) * s_t


def gsf_from_turn(i1: float, i1_turned: float, turn_deg: float = 1.0) -> float:
    """GSF = 900/(I1 - I1') for a +1 deg turn about the vertical (eq. 14); any latitude."""
    diff = i1 - i1_turned
    if diff == 0.0:
        raise ValueError("I1 - I1' is zero: the turn produced no change in torquer current")
    return 3600.0 * turn_deg / (4.0 * diff)
