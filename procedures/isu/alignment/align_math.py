"""Alignment matrices of Part III (Charts III-3, III-7, III-11) and the error of an alignment.

Convention (one for the whole project, as ``procedures.isu.survey_math``): T_ij = E_i . B_j, with
earth axes E1 = up (U), E2 = east (E), E3 = north (N). The columns of T are the body axes in
earth components and the rows are the earth axes in body components, so T = T^EB =
(T^BE)^T and a body vector v_B has earth components T v_B. The mirror alignment's first
column is (U.M1, E.M1, N.M1) exactly as Chart III-3 prints it, and Charts III-7 and III-11
build T as a product whose rows are U, E and N in body components: the same matrix.

Error of an alignment (``rotation_error``): the estimate is the truth turned by a small
rotation phi about earth axes, T_est = (I + [phi x]) T_true, so [phi x] is the skew part of
T_est T_true^T - I. phi_U is the azimuth error (positive: the estimated body axes turned
counter-clockwise seen from above, from east towards north), phi_E and phi_N the level errors
about east and about north. ``tests/test_alignment.py`` proves the convention against the
simulator's true attitude (world.attitude(t) is T^BE).

Angles are in degrees at this interface, specific force in g, rates in deg/hr (any unit
works for g and omega: only directions and ratios enter).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from procedures.isu.calibration.vectors import cross3
from procedures.isu.survey_math import direction, mirror_alignment

ARCSEC = math.pi / (180.0 * 3600.0)
AXES = ("U", "E", "N")

__all__ = [
    "ARCSEC",
    "direction",
    "gyrocompass_matrix",
    "level_matrix",
    "mirror_alignment",
    "rotation_error",
    "rotation_error_arcsec",
]


def _unit(v: np.ndarray, what: str) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if not n > 0.0:
        raise ValueError(f"{what} is zero: the alignment matrix is undefined")
    return v / n


def level_matrix(
    g_b: ArrayLike,
    alpha1_deg: float,
    *,
    theta1_deg: float | None = None,
    g_survey: float | None = None,
) -> np.ndarray:
    """Chart III-7: T from the body components of g and the azimuth alpha1 of mirror 1.

    The chart is the product R(alpha1) P(M1.U) S(U), whose rows are, in turn, (B1, U,
    B1 x U) in body components, then U, the horizontal unit vector across M1 and the
    horizontal unit vector along M1, then U, E and N. The chart prints the third row of the
    middle matrix as [1, +(M1.U), 0] / |M1 x U|, which is not horizontal; the horizontal
    projection of M1 is (B1 - (M1.U) U) / |M1 x U| (Chart III-11 has the minus sign in the
    same place), so the sign is taken as minus here.

    Options (III-2.2): ``theta1_deg``, the zenith of mirror 1 from the autocollimator, gives
    M1.U = cos(theta1) instead of U.B1; ``g_survey`` (g) replaces |g| computed from the three
    accelerometers (a survey value would let two accelerometers serve).
    """
    g_b = np.asarray(g_b, dtype=float)
    g = float(np.linalg.norm(g_b)) if g_survey is None else float(g_survey)
    u = g_b / g  # (U.B1, U.B2, U.B3)
    m1u = float(u[0]) if theta1_deg is None else math.cos(math.radians(theta1_deg))
    s = math.sqrt(max(0.0, 1.0 - m1u * m1u))  # |M1 x U|
    if s < 1e-9:
        raise ValueError("mirror 1 is vertical: its azimuth does not fix the alignment")
    a = math.radians(alpha1_deg)
    r_alpha = np.array(
        [[1.0, 0.0, 0.0], [0.0, math.sin(a), math.cos(a)], [0.0, -math.cos(a), math.sin(a)]]
    )
    # derived sign: -(M1.U) (see the docstring; the chart prints +)
    p = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0 / s], [1.0 / s, -m1u / s, 0.0]])
    rows = np.array([[1.0, 0.0, 0.0], u, [0.0, -u[2], u[1]]])  # B1, U, B1 x U (body)
    return r_alpha @ p @ rows


def gyrocompass_matrix(
    g_b: ArrayLike,
    w_b: ArrayLike,
    *,
    colatitude_deg: float | None = None,
    g_survey: float | None = None,
    w_survey: float | None = None,
) -> np.ndarray:
    """Chart III-11: T from the body components of g and of the Earth rate.

    Rows U, E = (W x U)/|W x U| and N = (W - (W.U) U)/|W x U| in body components (as
    printed). Options (III-3.2): ``colatitude_deg`` gives W.U = cos(lambda) (lambda is the
    colatitude in report 000); ``g_survey`` (g) and ``w_survey`` (deg/hr, the units of
    ``w_b``) replace the magnitudes computed from the instruments. With options the rows
    are no longer exactly orthonormal when the measurements disagree with them, as in the
    report; ``rotation_error`` reads the rotation part.
    """
    g_b = np.asarray(g_b, dtype=float)
    w_b = np.asarray(w_b, dtype=float)
    g = float(np.linalg.norm(g_b)) if g_survey is None else float(g_survey)
    w = float(np.linalg.norm(w_b)) if w_survey is None else float(w_survey)
    if not (g > 0.0 and w > 0.0):
        raise ValueError("g or the Earth rate is zero: the alignment matrix is undefined")
    u = g_b / g
    wn = w_b / w
    wu = float(wn @ u) if colatitude_deg is None else math.cos(math.radians(colatitude_deg))
    s = math.sqrt(max(0.0, 1.0 - wu * wu))  # |W x U|
    if s < 1e-9:
        raise ValueError("the Earth rate is vertical (at a pole): no north to find")
    first = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0 / s], [1.0 / s, -wu / s, 0.0]])
    rows = np.array([wn, u, cross3(wn, u)])  # W, U, W x U in body components
    return first @ rows


def rotation_error(t_est: ArrayLike, t_true: ArrayLike) -> np.ndarray:
    """Small rotation phi (U, E, N components, rad) with T_est = (I + [phi x]) T_true."""
    r = np.asarray(t_est, dtype=float) @ np.asarray(t_true, dtype=float).T
    return 0.5 * np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])


def rotation_error_arcsec(t_est: ArrayLike, t_true: ArrayLike) -> dict[str, float]:
    """Level errors about east and north and the azimuth error (about up), arcsec."""
    phi = rotation_error(t_est, t_true) / ARCSEC
    return {"east": float(phi[1]), "north": float(phi[2]), "azimuth": float(phi[0])}
