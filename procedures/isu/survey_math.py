"""System survey computations (report 000, Charts I-4, I-5, I-6 and III-3), pure numpy.

Conventions (DOMAIN.md section 1): T^XY_ij = X_i . Y_j, products compose left to right,
T^BE = T^BI T^IO T^OR T^RT T^TF T^FE; earth axes E1 up, E2 east, E3 north. Angles are in
degrees at this interface (radians inside).

Every formula below was derived from that geometry and checked against the printed charts:
Charts I-4, I-5, I-6 and III-3 agree with the derivation as printed, so their closed forms
are kept. (Only the report's running text slips: it calls the Survey Results Sheet
"Chart I-1" and "Chart I-2"; it is Chart I-3.) Chart I-4's T^FE = I is an assumption about
the table base, not an identity: ``procedures.isu.system_survey`` corrects for the base's tilt
and azimuth before entering position 0 here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

# Body vector put along the rotary axis R1 in each surveyed calibration position (Chart I-5);
# positions 2, 4, 6 are 1, 3, 5 with phi3 + 180 deg, positions 7-15 reuse these settings.
_R2 = math.sqrt(0.5)
POSITION_VECTORS: dict[int, tuple[float, float, float]] = {
    1: (1.0, 0.0, 0.0),
    3: (0.0, 1.0, 0.0),
    5: (0.0, 0.0, 1.0),
    13: (_R2, _R2, 0.0),
    14: (_R2, 0.0, _R2),
    15: (0.0, _R2, _R2),
}
SURVEYED_POSITIONS = tuple(POSITION_VECTORS)


def gimbal(p_deg: float) -> np.ndarray:
    """Chart I-4 gimbal transform T^XY(p) = [[0,1,0],[cos p,0,-sin p],[-sin p,0,-cos p]].

    The same form serves T^IO(phi4), T^OR(phi3), T^RT(phi2) and T^TF(phi1): the inner frame's
    axis 1 is the outer frame's axis 2 (the gimbal axis), and increasing p turns the inner
    frame positively about that axis.
    """
    p = math.radians(p_deg)
    c, s = math.cos(p), math.sin(p)
    return np.array([[0.0, 1.0, 0.0], [c, 0.0, -s], [-s, 0.0, -c]])


def t_ie(position_deg: Sequence[float] | np.ndarray) -> np.ndarray:
    """T^IE = T^IO(phi4) T^OR(phi3) T^RT(phi2) T^TF(phi1) T^FE with T^FE = I (Chart I-4).

    ``position_deg`` = (phi1, phi2, phi3, phi4).
    """
    p1, p2, p3, p4 = (float(x) for x in position_deg)
    return gimbal(p4) @ gimbal(p3) @ gimbal(p2) @ gimbal(p1)


def direction(az_deg: float, zen_deg: float) -> np.ndarray:
    """Unit vector (U, E, N) of an autocollimator reading (Chart III-3).

    Zenith from up; azimuth from east towards north: (cos th, cos a sin th, sin a sin th).
    """
    a, th = math.radians(az_deg), math.radians(zen_deg)
    return np.array([math.cos(th), math.cos(a) * math.sin(th), math.sin(a) * math.sin(th)])


def angles(vector: ArrayLike) -> tuple[float, float]:
    """(azimuth in [0, 360), zenith) in degrees of a vector (U, E, N); inverse of ``direction``."""
    v = np.asarray(vector, dtype=float)
    v = v / np.linalg.norm(v)
    zen = math.degrees(math.acos(max(-1.0, min(1.0, float(v[0])))))
    az = math.degrees(math.atan2(float(v[2]), float(v[1]))) % 360.0
    return az, zen


def rotation_about(axis: ArrayLike, angle_deg: float) -> np.ndarray:
    """Matrix turning vectors positively (right hand) by ``angle_deg`` about unit ``axis``."""
    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    a = math.radians(angle_deg)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(a) * kx + (1.0 - math.cos(a)) * (kx @ kx)


def rotation_axis_angle(r: np.ndarray) -> tuple[np.ndarray, float]:
    """(unit axis, angle in degrees) of a rotation matrix (angle in [0, 180))."""
    r = np.asarray(r, dtype=float)
    w = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    s = 0.5 * float(np.linalg.norm(w))
    c = 0.5 * (float(np.trace(r)) - 1.0)
    if s < 1e-15:
        raise ValueError("no rotation: the axis is undefined")
    return w / (2.0 * s), math.degrees(math.atan2(s, c))


def trunnion_axis_azimuth(t_a: np.ndarray, t_b: np.ndarray) -> dict:
    """Trunnion axis in the earth frame from two alignment matrices (Chart III-3, T = T^EB).

    Between readings a and b only phi1 turned. The chain T^BE = T^BI ... T^TF(phi1) T^FE
    turns the body about F2, the trunnion axis, whatever lies inside, so T_a T_b^T is a
    rotation about F2 (E components) by phi1_b - phi1_a. With a perfect base F2 is east;
    its azimuth is the turn of the base about the vertical, which at phi1 = 0 is a turn
    about the rotary axis R1 and adds to phi2 exactly (phi2 + azimuth), and its elevation is
    the base tilt about north. Angles in arcsec; ``angle_deg`` for checking against the
    resolvers.
    """
    axis, ang = rotation_axis_angle(np.asarray(t_a) @ np.asarray(t_b).T)
    if axis[1] < 0:
        axis = -axis
    az = math.degrees(math.atan2(axis[2], axis[1])) * 3600.0
    el = math.degrees(math.asin(max(-1.0, min(1.0, float(axis[0]))))) * 3600.0
    return {"azimuth_arcsec": az, "elevation_arcsec": el, "angle_deg": ang}


def mirror_alignment(alpha1: float, theta1: float, alpha2: float, theta2: float) -> np.ndarray:
    """Chart III-3 alignment matrix T from the two mirror normals' azimuths and zeniths (deg).

    Convention: T_ij = E_i . B_j, i.e. the columns of T are the body axes in earth (U, E, N)
    components, so T = T^EB = (T^BE)^T. Column 1 is M1 (= B1); column 2 is the part of M2
    normal to M1, normalised (B2: mirror 2 lies in the B1-B2 plane, so its small
    non-orthogonality to mirror 1 drops out); column 3 is M1 x M2 / |M1 x M2| (B3). The
    chart's dot and cross products reduce to exactly these, e.g.
    (M1 x U).(M1 x M2) = U.M2 - (M1.M2)(U.M1).
    """
    m1 = direction(alpha1, theta1)
    m2 = direction(alpha2, theta2)
    c12 = float(m1 @ m2)
    s12 = math.sqrt(max(0.0, 1.0 - c12 * c12))  # |M1 x M2| (Chart III-3)
    if s12 < 1e-9:
        raise ValueError("mirror normals are parallel: the alignment matrix is undefined")
    b2 = (m2 - c12 * m1) / s12
    b3 = np.cross(m1, m2) / s12
    return np.column_stack([m1, b2, b3])


def t_bi_from_survey(position0_deg: Sequence[float] | np.ndarray,
                     autocollimator_deg: Sequence[float] | np.ndarray) -> np.ndarray:
    """Chart I-4: T^BI = (T^BS0 T^SE0) (T^IO0 T^OR0 T^RT0 T^TF0 T^FE)^-1.

    ``position0_deg`` = (phi1, phi2, phi3, phi4) at position 0; ``autocollimator_deg`` =
    (alpha1, theta1, alpha2, theta2). The autocollimators give T^BE = T^T (Chart III-3), and
    the inverse of the orthogonal gimbal chain is its transpose.
    """
    a1, th1, a2, th2 = (float(x) for x in autocollimator_deg)
    t_be = mirror_alignment(a1, th1, a2, th2).T
    return t_be @ t_ie(position0_deg).T


def settings_for(t_bi: np.ndarray, b: ArrayLike) -> tuple[float, float]:
    """(phi3, phi4) in degrees putting body vector ``b`` (unit, B components) along R1.

    Chart I-5: R1 in I components is the first column of T^IO T^OR (Chart I-6),
    (cos phi3, sin phi3 sin phi4, sin phi3 cos phi4); it must equal T^IB b, i.e. the
    combination of the rows of T^BI that ``b`` selects. phi3 in [0, 180], phi4 in [0, 360).
    """
    u = np.asarray(b, dtype=float) @ np.asarray(t_bi, dtype=float)
    u = u / np.linalg.norm(u)
    phi3 = math.degrees(math.acos(max(-1.0, min(1.0, float(u[0])))))
    if math.hypot(u[1], u[2]) < 1e-12:
        phi4 = 0.0  # b already along I1: phi4 is free
    else:
        phi4 = math.degrees(math.atan2(float(u[1]), float(u[2]))) % 360.0
    return phi3, phi4


def resolver_settings(t_bi: np.ndarray) -> dict[int, tuple[float, float]]:
    """Chart I-5: (phi3^m, phi4^m) in degrees for m = 1, 3, 5, 13, 14, 15."""
    return {m: settings_for(t_bi, b) for m, b in POSITION_VECTORS.items()}


def t_ir(phi3: float, phi4: float) -> np.ndarray:
    """T^IO(phi4) T^OR(phi3), the matrix printed in Chart I-6 (degrees in)."""
    return gimbal(phi4) @ gimbal(phi3)


def t_br(t_bi: np.ndarray, phi3: float, phi4: float) -> np.ndarray:
    """Chart I-6: T^BRm = T^BI T^IOm T^ORm (degrees in)."""
    return np.asarray(t_bi, dtype=float) @ t_ir(phi3, phi4)


def t_br_column2(t_bi: np.ndarray, phi3: float, phi4: float) -> tuple[float, float, float]:
    """Chart I-6 step 3: (T12, T22, T32)^BRm = T^BI_i2 cos phi4 - T^BI_i3 sin phi4.

    It does not depend on phi3 (R2 = O1 is the outer axis, turned only by phi4).
    """
    t = np.asarray(t_bi, dtype=float)
    p4 = math.radians(phi4)
    col = t[:, 1] * math.cos(p4) - t[:, 2] * math.sin(p4)
    return float(col[0]), float(col[1]), float(col[2])


def t_br_column3(t_bi: np.ndarray, phi3: float, phi4: float) -> tuple[float, float, float]:
    """Chart I-6 step 4 (for information): (T13, T23, T33)^BRm = -T^BI_i1 sin phi3
    + T^BI_i2 cos phi3 sin phi4 + T^BI_i3 cos phi3 cos phi4, the third column of
    T^BI T^IOm T^ORm."""
    t = np.asarray(t_bi, dtype=float)
    p3, p4 = math.radians(phi3), math.radians(phi4)
    col = (-t[:, 0] * math.sin(p3) + t[:, 1] * math.cos(p3) * math.sin(p4)
           + t[:, 2] * math.cos(p3) * math.cos(p4))
    return float(col[0]), float(col[1]), float(col[2])


def rotation_angle_arcsec(a: np.ndarray, b: np.ndarray) -> float:
    """Angle of the rotation a b^T between two orthogonal matrices, arcsec."""
    r = np.asarray(a, dtype=float) @ np.asarray(b, dtype=float).T
    c = max(-1.0, min(1.0, (float(np.trace(r)) - 1.0) / 2.0))
    # near zero acos loses precision: use the skew part instead
    s = 0.5 * math.sqrt(
        (r[2, 1] - r[1, 2]) ** 2 + (r[0, 2] - r[2, 0]) ** 2 + (r[1, 0] - r[0, 1]) ** 2
    )
    return math.degrees(math.atan2(s, c)) * 3600.0
