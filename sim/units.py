"""The one place where the laboratory's units are converted to and from SI."""

from __future__ import annotations

import math

G0 = 9.80665  # m/s^2; the unit "g" of the lab's coefficients (deg/hr/g, g/g^2, ...)
ARCSEC = math.pi / (180.0 * 3600.0)  # rad
DEG = math.pi / 180.0  # rad
HOUR = 3600.0  # s
DEG_PER_HR = DEG / HOUR  # rad/s
SIDEREAL_DAY = 86164.0905  # s
EARTH_RATE = 2.0 * math.pi / SIDEREAL_DAY  # rad/s (7.292115e-5)
MICRO_G = 1e-6 * G0  # m/s^2


def arcsec(x: float) -> float:
    """Arc-seconds to radians."""
    return x * ARCSEC


def to_arcsec(rad: float) -> float:
    """Radians to arc-seconds."""
    return rad / ARCSEC


def deg_per_hr(x: float) -> float:
    """deg/hr to rad/s."""
    return x * DEG_PER_HR


def to_deg_per_hr(rad_s: float) -> float:
    """rad/s to deg/hr."""
    return rad_s / DEG_PER_HR
