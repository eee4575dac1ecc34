"""Alignment results against what the survey and the site already know.

* Mirror alignment (Chart III-2): T at position 0 as the survey predicts it (Chart I-4's
  T^BI, the resolvers and bubble levels at the alignment) against the measured T.
* Level and gyrocompass alignment (Charts III-4, III-8): T against the mirror alignment of
  the same run (else the survey's prediction), |g| against the survey's g; the gyrocompass's
  |omega| against the site's Earth rate and the angle between omega and the vertical
  against the site's colatitude.

Every comparison is in units of its own predicted sigma (the results' error models, the
survey's and the pier's from ``NoiseSpec``); beyond ``K_RESULT`` the step stops
(``Implausible``) naming the result, what it contradicts and the instruments whose data
made it. ``K_RESULT`` is set so that normal days essentially never stop (bench/result_checks.py
measures the largest |z| over a Monte Carlo of fault-free days).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from procedures.isu import survey_math as sm
from procedures.isu.alignment.align_math import ARCSEC, rotation_error_arcsec
from procedures.isu.alignment.preprocess import Constants
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.calibration.vectors import cross3, norm3
from procedures.isu.plausibility import Implausible
from procedures.isu.sheets import SurveyResults

if TYPE_CHECKING:
    from procedures.isu.alignment.common import Outcome

K_RESULT = 6.0  # a result this many of its sigmas from what is known stops the step
AXES = ("about east", "about north", "about up (azimuth)")
# survey-side terms of a predicted T at position 0 (arcsec): the survey's mean of 60
# autocollimator readings; two table settings; the level reading at the alignment and the
# survey's mean of its 120
SURVEY_READINGS = 60


def check(source: str, what: str, value: float, expected: float, sigma: float, unit: str,
          blame: str, k: float = K_RESULT) -> dict:
    """One comparison; Implausible beyond ``k`` sigma, else its record."""
    z = (value - expected) / sigma if sigma > 0 else (0.0 if value == expected else math.inf)
    if not abs(z) <= k:
        raise Implausible(source, f"{what} {value:.7g} {unit}, but {expected:.7g} {unit} is "
                          f"known: {z:+.1f} sigma (sigma {sigma:.3g} {unit}, limit {k:g}): "
                          f"{blame}")
    return {"value": value, "expected": expected, "sigma": sigma, "z": z}


def check_attitude(source: str, t: np.ndarray, sigma: Sequence[float], t_ref: np.ndarray,
                   sigma_ref: Sequence[float], reference: str, blame: str,
                   motion: Sequence[float] = (0.0, 0.0, 0.0), k: float = K_RESULT) -> dict:
    """T against a reference attitude, per axis (about east, north, up) in arcsec."""
    err = rotation_error_arcsec(t, t_ref)
    e = (err["east"], err["north"], err["azimuth"])
    out = {}
    for i, name in enumerate(AXES):
        s = math.sqrt(sigma[i] ** 2 + sigma_ref[i] ** 2 + motion[i] ** 2)
        out[name] = check(source, f"T {name} differs from {reference} by", e[i], 0.0, s,
                          "arcsec", blame, k)
    return out


def tilt_motion_arcsec(noise: NoiseSpec, dt: float) -> tuple[float, float, float]:
    """rms change of the pier's tilt (about east, about north; none in azimuth) over dt."""
    ee0, nn0, _ = noise.tilt_covariance(0.0)
    ee, nn, _ = noise.tilt_covariance(abs(dt))
    return (math.sqrt(max(2.0 * float(ee0 - ee), 0.0)) / ARCSEC,
            math.sqrt(max(2.0 * float(nn0 - nn), 0.0)) / ARCSEC, 0.0)


def survey_t(survey: SurveyResults, resolvers_deg: Sequence[float],
             level_arcsec: Sequence[float]) -> np.ndarray:
    """T (T^EB) at a position-0 setting as the survey predicts it: Chart I-4 turned round,
    T^BE = T^BI T^IE, with the setting entered as the survey entered its own (resolvers less
    the level corrections, phi2 plus the trunnion-axis azimuth of step 5a)."""
    dphi2 = survey.position0_deg[1] - 90.0  # azimuth of the base (+ the survey's phi2 setting)
    p1, p2, p3, p4 = (float(x) for x in resolvers_deg)
    c1, c3 = (float(x) for x in level_arcsec)
    phi = (p1 - c1 / 3600.0, p2 + dphi2, p3 - c3 / 3600.0, p4)
    return (np.asarray(survey.t_bi, dtype=float) @ sm.t_ie(phi)).T


def survey_sigma_arcsec(noise: NoiseSpec) -> tuple[float, float, float]:
    """1-sigma (about east, north, up) of the survey's prediction of T at position 0: the
    survey's mean autocollimator readings, the level readings (the alignment's one, the
    survey's mean), two table settings and, in azimuth, the base-azimuth step 5a."""
    ac = noise.autocollimator_arcsec / math.sqrt(SURVEY_READINGS)
    lev = noise.bubble_sigma / ARCSEC * math.sqrt(1.0 + 1.0 / (2 * SURVEY_READINGS))
    setting = noise.table_setting_arcsec * math.sqrt(2.0)
    level_axes = math.sqrt(ac**2 + lev**2 + setting**2)
    azimuth = math.sqrt(ac**2 + setting**2 + noise.survey_azimuth_arcsec**2)
    return level_axes, level_axes, azimuth


def cal_sigma(constants: Constants, f: Callable[[Constants], float]) -> float:
    """1-sigma of a scalar result f(constants) from the calibration constants' sigmas and
    their correlation (``Constants.rho``, as the alignment error models), by central
    differences."""
    moves: dict[tuple[str, str], float] = {}
    for key, s in constants.sigmas.items():
        if s:
            moves[key] = 0.5 * (f(constants.perturbed(key, s)) - f(constants.perturbed(key, -s)))
    keys = list(moves)
    d = np.array([moves[k] for k in keys])
    if not keys:
        return 0.0
    rho = constants.rho_matrix(keys)
    return math.sqrt(max(float(d @ rho @ d), 0.0))


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return math.degrees(math.atan2(norm3(cross3(a, b)), float(a @ b)))


def attitude_reference(survey: SurveyResults | None, surveyed_here: bool,
                       mirror: Outcome | None, position0: dict, noise: NoiseSpec,
                       t_result: float
                       ) -> tuple[np.ndarray, list[float], str, tuple[float, float, float]] | None:
    """What an alignment's T is compared with: the mirror alignment of this run (``mirror``,
    an Outcome), else the survey's prediction at the alignment's own setting when the survey
    was made in this run; with the pier's tilt change between the two times (the levelling
    and the result) and, against the mirror alignment, the two settings of the rotary axis
    (vertical at position 0: a turn in azimuth)."""
    if mirror is not None:  # each alignment set position 0 anew: two settings of phi2
        e, n, _ = tilt_motion_arcsec(noise, t_result - mirror.t_ref)
        return (np.asarray(mirror.t), list(mirror.predicted_sigma_arcsec),
                "the mirror alignment (Chart III-2)",
                (e, n, math.sqrt(2.0) * noise.table_setting_arcsec))
    if survey is not None and surveyed_here:
        t = survey_t(survey, position0["resolvers_deg"], position0["level_arcsec"])
        return (t, list(survey_sigma_arcsec(noise)), "the survey's T^BI (Chart I-3) at this "
                "setting", tilt_motion_arcsec(noise, t_result - float(position0["t_s"])))
    return None
