"""The error budget of report 001, Appendix II eqs. 26-27: what the four-orientation sum
leaves in theta besides the fixture's azimuth, term by term, and the eq. 27 correction.

Eq. 26 gives S_T (I2 + I4 - I1 - I3) = -4 b D_I + 4 c D_OS - 4 b w_E sin(lat)
+ 4 (a + d) w_E cos(lat) + (3 eps + eta) w_E cos(lat). The test's theta (eqs. 8, 28) is
minus that over 4 w_E cos(lat), so theta = -(a + d) + sum of the terms below; eq. 27 takes
them back out with the laboratory's own values of b, c, D_I, D_OS, eps and eta (the levels'
readings, the gyro's calibration, the fixture's null calibration), leaving -(a + d), the
fixture's azimuth error after the optical alignment (zero in the report's laboratory).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

EARTH_RATE_DEG_PER_HR = 15.041067  # one turn per sidereal day, in deg per (solar) hour

TERMS = (
    ("b D_I", "eq. 26 term -4 b D_I: b D_I / (w_E cos lat)"),
    ("c D_OS", "eq. 26 term 4 c D_OS: -c D_OS / (w_E cos lat)"),
    ("b omega sin", "eq. 26 term -4 b w_E sin lat: b tan lat"),
    ("(3 epsilon + eta)/4", "eq. 26 term (3 eps + eta) w_E cos lat: -(3 eps + eta) / 4"),
)


def budget_terms(b_arcsec: float, c_arcsec: float, d_i_deg_hr: float, d_os_deg_hr: float,
                 eps_arcsec: float, eta_arcsec: float, latitude_deg: float
                 ) -> dict[str, float]:
    """Each eq. 26 term's part of the uncorrected theta (eq. 28), arcsec, by TERMS name."""
    lat = math.radians(latitude_deg)
    wc = EARTH_RATE_DEG_PER_HR * math.cos(lat)
    return {
        "b D_I": b_arcsec * d_i_deg_hr / wc,
        "c D_OS": -c_arcsec * d_os_deg_hr / wc,
        "b omega sin": b_arcsec * math.tan(lat),
        "(3 epsilon + eta)/4": -(3.0 * eps_arcsec + eta_arcsec) / 4.0,
    }


@dataclass(frozen=True)
class Eq27Values:
    """What the laboratory knows for eq. 27, with the 1-sigma error of each: b and c from
    the bubble levels, D_I and D_OS from the gyro's calibration, the 180 deg vertical null's
    error from the fixture's calibration (eps = that error, eta = -eps: orientation 4
    returns to the 0 deg null)."""

    latitude_deg: float
    b_arcsec: float = 0.0
    c_arcsec: float = 0.0
    level_sigma_arcsec: float = 0.0
    d_i_deg_hr: float = 0.0
    d_os_deg_hr: float = 0.0
    drift_sigma_deg_hr: float = 0.0
    v180_error_arcsec: float = 0.0
    null_sigma_arcsec: float = 0.0

    def terms(self) -> dict[str, float]:
        """The laboratory's value of each budget term, arcsec."""
        e = self.v180_error_arcsec
        return budget_terms(self.b_arcsec, self.c_arcsec, self.d_i_deg_hr, self.d_os_deg_hr,
                            e, -e, self.latitude_deg)

    def sigmas(self) -> dict[str, float]:
        """Each term's 1-sigma error from the errors of the values it is made of."""
        lat = math.radians(self.latitude_deg)
        wc = EARTH_RATE_DEG_PER_HR * math.cos(lat)
        sb, sd = self.level_sigma_arcsec, self.drift_sigma_deg_hr
        return {
            "b D_I": math.hypot(sb * self.d_i_deg_hr, self.b_arcsec * sd) / wc,
            "c D_OS": math.hypot(sb * self.d_os_deg_hr, self.c_arcsec * sd) / wc,
            "b omega sin": sb * abs(math.tan(lat)),
            "(3 epsilon + eta)/4": self.null_sigma_arcsec / 2.0,
        }

    def correction(self) -> tuple[float, float]:
        """What eq. 27 takes off the uncorrected theta, and its 1-sigma error, arcsec. The
        b terms share b's error (b (tan lat + D_I / w_E cos lat) in one)."""
        t = self.terms()
        lat = math.radians(self.latitude_deg)
        wc = EARTH_RATE_DEG_PER_HR * math.cos(lat)
        sb, sd = self.level_sigma_arcsec, self.drift_sigma_deg_hr
        var = ((sb * (math.tan(lat) + self.d_i_deg_hr / wc)) ** 2
               + (sb * self.d_os_deg_hr / wc) ** 2
               + ((self.b_arcsec * sd) ** 2 + (self.c_arcsec * sd) ** 2) / wc**2
               + (self.null_sigma_arcsec / 2.0) ** 2)
        return sum(t.values()), math.sqrt(var)


def budget_rows(truth: dict[str, float] | None, lab: Eq27Values | None) -> list[dict]:
    """The budget table: per term its equation, the simulator's true value (None on a real
    rack) and, with eq. 27, the laboratory's value and its sigma; a total row last."""
    have = lab.terms() if lab is not None else None
    sig = lab.sigmas() if lab is not None else None
    rows = []
    for name, text in TERMS:
        rows.append({"term": name, "equation": text,
                     "lab_arcsec": None if have is None else have[name],
                     "lab_sigma_arcsec": None if sig is None else sig[name],
                     "truth": None if truth is None else truth[name]})
    corr = lab.correction() if lab is not None else None
    rows.append({"term": "total", "equation": "theta (eq. 28) + (a + d)",
                 "lab_arcsec": None if corr is None else corr[0],
                 "lab_sigma_arcsec": None if corr is None else corr[1],
                 "truth": None if truth is None else sum(truth[n] for n, _ in TERMS)})
    return rows


def corrected_phases(phases: list[dict], lab: Eq27Values) -> list[dict]:
    """Eq. 27 applied to each phase: theta less the correction, sigmas added in quadrature
    (the correction is common to every run, so it adds to the phase, not the run)."""
    corr, s = lab.correction()
    return [{"phase": p["phase"], "n": p["n"], "theta_arcsec": p["theta_arcsec"] - corr,
             "sigma_arcsec": math.hypot(p["sigma_arcsec"], s), "correction_arcsec": corr,
             "correction_sigma_arcsec": s} for p in phases]
