"""The pre-test set-up aids of the CIGTF fixture (report 001, section 4.1).

"Prior to the start of the test, the vertical test fixture axis is aligned parallel to the
local gravity vector by means of bubble levels mounted on the vertical axis mounting
surface. In addition, the horizontal axis is aligned parallel to the horizontal component
of earth rotation rate by optical means." Here:

* two bubble levels on the vertical axis's mounting surface, turning with it: the EW level
  along the surface's Z_V (it reads b at vertical 0, -b at 180), the NS level along Y_V
  (-c at 0, +c at 180), each with a zero offset (the level's and the surface's own error,
  which the half-difference of the 0 and 180 deg readings cancels);
* levelling screws that tilt the vertical axis so a level at vertical 0 reads a commanded
  amount more (``tilt``), each adjustment off by a seeded fraction (``adjust_error``);
* an autocollimator sighting a mirror on the horizontal axis from the laboratory's north
  reference: it reads the horizontal axis's azimuth (a + d, positive from north toward
  west, Appendix II) plus the mirror's error, which changes sign when the horizontal axis
  turns 180 deg (the half-sum of the two readings cancels it);
* a base azimuth adjustment turning the fixture about its vertical axis (a), off by a
  seeded fraction like the screws.

The readings are exact functions of the fixture's frames (``fixture.q_ge`` conventions),
plus white noise and the instruments' resolution. The north reference is taken as true.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from sim.cigtf.fixture import GyrocompassFixture, rot_x, rot_y
from sim.rng import stream
from sim.units import ARCSEC, to_arcsec


@dataclass(frozen=True)
class SetupSpec:
    """Installed misalignments before the set-up and the set-up aids' errors (arcsec)."""

    installed_tilt_sd_arcsec: float = 60.0  # b, c as the fixture stands on its pier
    installed_azimuth_sd_arcsec: float = 300.0  # a before the optical alignment
    level_noise_arcsec: float = 0.3  # 1 sigma, one bubble-level reading
    level_resolution_arcsec: float = 0.1
    level_offset_sd_arcsec: float = 20.0  # each level's zero on the mounting surface
    collimator_noise_arcsec: float = 0.2  # 1 sigma, one autocollimator reading
    collimator_resolution_arcsec: float = 0.1
    mirror_sd_arcsec: float = 30.0  # mirror normal off the horizontal axis, in azimuth
    adjust_error: float = 0.05  # 1-sigma fractional error of one screw or base adjustment


def quantise(x: float, step: float) -> float:
    """A reading to the instrument's resolution."""
    return round(x / step) * step if step > 0 else x


class SetupAids:
    """Bubble levels, levelling screws, autocollimator and base adjustment of one fixture."""

    def __init__(self, fixture: GyrocompassFixture, spec: SetupSpec, seed: int) -> None:
        self.fixture, self.spec, self.seed = fixture, spec, seed
        rng = stream(seed, "cigtf_setup", "fixed")
        self.level_offsets = tuple(float(x) * ARCSEC
                                   for x in rng.normal(0.0, spec.level_offset_sd_arcsec, 2))
        self.mirror = float(rng.normal(0.0, spec.mirror_sd_arcsec)) * ARCSEC
        self._draws = 0

    def _rng(self, what: str) -> np.random.Generator:
        self._draws += 1
        return stream(self.seed, "cigtf_setup", what, self._draws)

    def true_levels(self) -> tuple[float, float]:
        """Slopes the EW and NS levels see now (radians, without offset or noise): the
        up-components of Z_V and Y_V at the actual vertical angle."""
        v, _ = self.fixture.angles()
        q = rot_x(v) @ self.fixture.misalignments.q_ve()  # Earth to vertical-axis frame
        return math.asin(float(q[2, 0])), math.asin(float(q[1, 0]))

    def levels_arcsec(self) -> tuple[float, float]:
        """One reading of the EW and NS bubble levels, arcsec."""
        noise = self._rng("level").normal(0.0, self.spec.level_noise_arcsec, 2)
        return tuple(  # type: ignore[return-value]
            quantise(to_arcsec(s + o) + float(n), self.spec.level_resolution_arcsec)
            for s, o, n in zip(self.true_levels(), self.level_offsets, noise, strict=True))

    def true_azimuth(self) -> float:
        """Azimuth of the horizontal axis now (radians, from north toward west, a + d to
        first order), from its direction in the Earth frame."""
        v, h = self.fixture.angles()
        m = self.fixture.misalignments
        q = rot_y(h) @ m.q_hv() @ rot_x(v) @ m.q_ve()  # Earth to horizontal-axis frame
        return math.atan2(float(q[1, 2]), float(q[1, 1]))

    def azimuth_arcsec(self) -> float:
        """One autocollimator reading, arcsec: the axis's azimuth and the mirror's error,
        whose sign follows the horizontal axis's turn (cos h)."""
        _, h = self.fixture.angles()
        noise = float(self._rng("collimator").normal(0.0, self.spec.collimator_noise_arcsec))
        return quantise(to_arcsec(self.true_azimuth() + self.mirror * math.cos(h)) + noise,
                        self.spec.collimator_resolution_arcsec)

    def _done(self, arcsec: float) -> float:
        """The angle an adjustment commanded as ``arcsec`` actually makes, radians."""
        k = float(self._rng("adjust").normal(0.0, self.spec.adjust_error))
        return arcsec * (1.0 + k) * ARCSEC

    def tilt(self, level: str, arcsec: float) -> None:
        """Levelling screws: the EW (NS) level at vertical 0 to read ``arcsec`` more."""
        m = self.fixture.misalignments
        x = self._done(arcsec)
        self.fixture.misalignments = (replace(m, b=m.b + x) if level == "EW"
                                      else replace(m, c=m.c - x))

    def turn_base(self, arcsec: float) -> None:
        """Base azimuth adjustment: the autocollimator to read ``arcsec`` more."""
        m = self.fixture.misalignments
        self.fixture.misalignments = replace(m, a=m.a + self._done(arcsec))
