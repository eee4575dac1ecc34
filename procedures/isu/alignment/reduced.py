"""Alignments with fewer instruments (III-2.2, III-3.2).

III-2.2 notes that a surveyed |g| lets two accelerometers serve the level alignment; III-3.2
that |g|, |omega^E| and the latitude from a survey reduce the gyrocompass alignment to three
instruments (two accelerometers and a gyro, or one accelerometer and two gyros). The report
gives no computation for either; ours (docs/alignment-options.md):

* level, two accelerometers: the absent accelerometer's component of g is sqrt(g^2 - the
  others'^2), with the sign of the nominal attitude; then Chart III-7 with the surveyed g.
  Only the component of an axis near the vertical is determined this way: an absent
  accelerometer whose axis is within 60 deg of horizontal at the alignment position is refused.
* gyrocompass, any set of at least three instruments with at least one of each kind: T is
  the rotation, found by Gauss-Newton from the nominal attitude, whose rows U and
  W = cos(c) U + sin(c) N (c the colatitude) reproduce the normalised components the present
  instruments measure (least squares when there are more than three). A set whose components
  leave a rotation undetermined at the alignment position is refused, naming the set.

The predicted sigmas come from the same Jacobians as the full alignments (the solution is
differentiated through this module), so they carry the geometry of the reduced set.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from station.errors import CheckFailed

ALL = (1, 2, 3)
MIN_VERTICAL = 0.5  # |U.A_k| of an absent accelerometer's axis: within 60 deg of vertical
MIN_SENSITIVITY = 0.05  # smallest singular value of d(components)/d(rotation), per rad


@dataclass(frozen=True)
class Instruments:
    """The accelerometers and gyros an alignment uses, and the nominal attitude (T^EB at the
    alignment position) that fixes the signs and starts the solution."""

    accels: tuple[int, ...] = ALL
    gyros: tuple[int, ...] = ALL
    t_prior: np.ndarray | None = None

    @property
    def reduced(self) -> bool:
        return self.accels != ALL or self.gyros != ALL

    def describe(self) -> str:
        return (f"accelerometers {', '.join(map(str, self.accels))} and gyros "
                f"{', '.join(map(str, self.gyros))}")


def orthonormalize(t: np.ndarray) -> np.ndarray:
    """The rotation nearest ``t``."""
    u, _, vt = np.linalg.svd(t)
    return u @ vt


def _prior(inst: Instruments) -> np.ndarray:
    if inst.t_prior is None:
        raise ValueError("a reduced instrument set needs the nominal attitude")
    return np.asarray(inst.t_prior, dtype=float)


def check_level_set(inst: Instruments) -> None:
    """CheckFailed when two accelerometers and |g| cannot fix the vertical (III-2.2)."""
    if len(inst.accels) < 2:
        raise CheckFailed("level alignment needs at least two accelerometers (III-2.2)")
    t = _prior(inst)
    for k in set(ALL) - set(inst.accels):
        if abs(t[0, k - 1]) < MIN_VERTICAL:
            raise CheckFailed(
                f"accelerometer {k} may be left out of the level alignment only when its axis "
                f"is near the vertical: at this position U.B{k} = {t[0, k - 1]:+.3f}, so two "
                "accelerometers and |g| leave that tilt undetermined (III-2.2)")


def complete_gravity(g_b: np.ndarray, inst: Instruments, g_survey: float) -> np.ndarray:
    """g_B with each absent accelerometer's component from |g| (III-2.2); g_b as given when
    all three are present."""
    g_b = np.asarray(g_b, dtype=float)
    missing = [k - 1 for k in ALL if k not in inst.accels]
    if not missing:
        return g_b
    t = _prior(inst)
    out = g_b.copy()
    out[missing] = 0.0
    (k,) = missing  # check_level_set: two accelerometers at least
    rest = float(out @ out)
    out[k] = math.copysign(math.sqrt(max(g_survey * g_survey - rest, 0.0)), t[0, k])
    return out


def _components(t: np.ndarray, inst: Instruments, cos_c: float, sin_c: float) -> np.ndarray:
    """What the present instruments see of U and W, unit vectors, for T^EB = t."""
    a = [k - 1 for k in inst.accels]
    g = [k - 1 for k in inst.gyros]
    w = cos_c * t[0, :] + sin_c * t[2, :]
    return np.concatenate((t[0, a], w[g]))


def _rotated(t: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """T^EB after a small rotation phi of the body (earth components), orthonormal."""
    x, y, z = phi
    skew = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return orthonormalize((np.eye(3) - skew + 0.5 * skew @ skew) @ t)


def _jacobian(t: np.ndarray, inst: Instruments, cos_c: float, sin_c: float) -> np.ndarray:
    h = 1e-6
    cols = []
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        cols.append((_components(_rotated(t, e), inst, cos_c, sin_c)
                     - _components(_rotated(t, -e), inst, cos_c, sin_c)) / (2 * h))
    return np.column_stack(cols)


def check_gyrocompass_set(inst: Instruments, colatitude_deg: float) -> None:
    """CheckFailed when the set leaves a rotation undetermined at the nominal attitude."""
    if not inst.accels or not inst.gyros or len(inst.accels) + len(inst.gyros) < 3:
        raise CheckFailed("gyrocompass alignment needs three instruments at least, with an "
                          f"accelerometer and a gyro (III-3.2); got {inst.describe()}")
    c = math.radians(colatitude_deg)
    sv = np.linalg.svd(_jacobian(_prior(inst), inst, math.cos(c), math.sin(c)),
                       compute_uv=False)
    if sv[-1] < MIN_SENSITIVITY:
        raise CheckFailed(
            f"{inst.describe()} do not determine the attitude at this position (their "
            f"components change by {sv[-1]:.2g} per rad of the least seen rotation; at least "
            f"{MIN_SENSITIVITY:g} is needed): keep the gyro whose axis is nearest east, or "
            "the accelerometers whose axes are horizontal (III-3.2)")


def gyrocompass_attitude(g_b: np.ndarray, w_b: np.ndarray, inst: Instruments, g_survey: float,
                         w_survey: float, colatitude_deg: float) -> np.ndarray:
    """T from the present instruments' components of g and omega^E (see the module doc)."""
    c = math.radians(colatitude_deg)
    cos_c, sin_c = math.cos(c), math.sin(c)
    a = [k - 1 for k in inst.accels]
    g = [k - 1 for k in inst.gyros]
    measured = np.concatenate((np.asarray(g_b, dtype=float)[a] / g_survey,
                               np.asarray(w_b, dtype=float)[g] / w_survey))
    t = _prior(inst)
    for _ in range(20):
        j = _jacobian(t, inst, cos_c, sin_c)
        r = measured - _components(t, inst, cos_c, sin_c)
        step = np.linalg.lstsq(j, r, rcond=None)[0]
        t = _rotated(t, step)
        if float(np.max(np.abs(step))) < 1e-13:
            break
    return t
