"""Two-axis gyrocompassing fixture of report 001 (section 3, Appendix II frames).

Earth frame E: X up, Y astronomic north, Z west. The vertical axis is X_V, the horizontal
axis Y_H; gyro axes are X_G = O, Y_G = S, Z_G = I. Matrices transform vector components
from the right-hand frame to the left-hand one, with the report's sign conventions, but
exact (not small-angle). Angles are radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.rng import stream
from sim.units import ARCSEC


def rot_x(a: float) -> np.ndarray:
    """Frame rotation about X as Appendix II writes it for a and the vertical axis."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])


def rot_y(b: float) -> np.ndarray:
    """Frame rotation about Y as Appendix II writes it for b and the horizontal axis."""
    c, s = math.cos(b), math.sin(b)
    return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])


def rot_z(g: float) -> np.ndarray:
    """Frame rotation about Z as Appendix II writes it for c."""
    c, s = math.cos(g), math.sin(g)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def small_rotation(x: float, y: float, z: float) -> np.ndarray:
    """Exact Z(z) Y(y) X(x): Q_VE for (a, b, c), Q_HV for (d, e, f), Q_GH for (h, i, j)."""
    return rot_z(z) @ rot_y(y) @ rot_x(x)


@dataclass(frozen=True)
class Misalignments:
    """Angles a..j of Appendix II, radians (d, e, f hold the non-perpendicularity)."""

    a: float = 0.0
    b: float = 0.0
    c: float = 0.0
    d: float = 0.0
    e: float = 0.0
    f: float = 0.0
    h: float = 0.0
    i: float = 0.0
    j: float = 0.0

    def q_ve(self) -> np.ndarray:
        """Earth to vertical-axis frame."""
        return small_rotation(self.a, self.b, self.c)

    def q_hv(self) -> np.ndarray:
        """Vertical-axis to horizontal-axis frame."""
        return small_rotation(self.d, self.e, self.f)

    def q_gh(self) -> np.ndarray:
        """Horizontal-axis to gyro frame."""
        return small_rotation(self.h, self.i, self.j)


def q_ge(m: Misalignments, vertical: float, horizontal: float) -> np.ndarray:
    """Earth to gyro frame at actual axis angles (Appendix II, sections 2.2-2.5)."""
    return m.q_gh() @ rot_y(horizontal) @ m.q_hv() @ rot_x(vertical) @ m.q_ve()


@dataclass(frozen=True)
class FixtureSpec:
    """Detent accuracy and repeatability (1-sigma), radians."""

    detent_error_sd: float = 0.5 * ARCSEC / 3.0
    repeatability_sd: float = 0.2 * ARCSEC / 3.0


@dataclass
class GyrocompassFixture:
    """Axis angles that land on 1-degree inductosyn nulls with fixed and random errors."""

    misalignments: Misalignments
    seed: int
    spec: FixtureSpec = field(default_factory=FixtureSpec)
    vertical_deg: int = 0
    horizontal_deg: int = 0
    _detents: dict[tuple[str, int], float] = field(default_factory=dict)
    _noise: tuple[float, float] = (0.0, 0.0)
    _moves: int = 0

    def _detent(self, axis: str, deg: int) -> float:
        key = (axis, deg % 360)
        if key not in self._detents:
            rng = stream(self.seed, "gyrocompass_fixture", "detent", axis, deg % 360)
            self._detents[key] = 0.0 if deg % 360 == 0 else float(
                rng.normal(0.0, self.spec.detent_error_sd))
        return self._detents[key]

    def move_to(self, vertical_deg: int, horizontal_deg: int) -> None:
        """Command both axes to whole-degree positions; each arrival draws repeatability."""
        self.vertical_deg, self.horizontal_deg = int(vertical_deg), int(horizontal_deg)
        self._moves += 1
        rng = stream(self.seed, "gyrocompass_fixture", "move", self._moves)
        nv, nh = rng.normal(0.0, self.spec.repeatability_sd, 2)
        self._noise = (float(nv), float(nh))

    def angles(self) -> tuple[float, float]:
        """Actual vertical and horizontal axis angles, radians."""
        v = math.radians(self.vertical_deg) + self._detent("v", self.vertical_deg) + self._noise[0]
        h = (math.radians(self.horizontal_deg) + self._detent("h", self.horizontal_deg)
             + self._noise[1])
        return v, h

    def q_ge(self) -> np.ndarray:
        """Earth to gyro frame now."""
        return q_ge(self.misalignments, *self.angles())
