"""Mirror and pickoff alignment as adjustments (report 004, "Mirror and Pickoff Alignment";
procedure step 1): from a coning turn, the shim that takes mirror 1 onto the spindle and
the translation that takes pickoff 1 onto it.

* Shim: the theodolite reads mirror 1's normal against the spindle on two lab-fixed axes
  while the spindle turns; each axis' first harmonic over the turn, evaluated at the
  spindle angle the shim is made at, is where mirror 1 points off the spindle there; the
  shim moves it back by that much.
* Translation (our derivation; the report says only that the pickoff is translated until
  its coning output is 15 arcsec or less): with the spin axis s across the spindle, pickoff
  1's direction cosine is alpha1(gamma) = const + d2 cos(psi - gamma) + d3 sin(psi - gamma),
  (d2, d3) its tilt off the spindle along the case axes c2, c3 and psi the angle of s in
  the c2-c3 plane at gamma = 0. Pickoff 2 (about c2) reads the equator where psi - gamma
  = -90 deg times the sign with which its colatitude grows with gamma, so
  psi = gamma_eq - sign * 90 deg. Near the equator d(CR)/d(theta) = slope and
  d(theta) = -d(alpha), so the count ratio's first harmonic (a cos g + b sin g) gives
  alpha1's as A = -a / slope, B = -b / slope; solving, d2 = A cos psi + B sin psi,
  d3 = A sin psi - B cos psi, and the translation is (-d2, -d3).
* The same for pickoff 2 with the case remounted, mirror 2 along the spindle and (c3, c1)
  in the places of (c2, c3) (the head's ``MOUNT 2``): its translation axes are c3, c1.
  There psi comes from pickoff 3 (along c3) instead: with s near c1 after damping,
  pickoff 3's direction cosine is cos(psi - gamma), so psi = gamma + its colatitude.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def first_harmonic(angles_deg: Sequence[float], values: Sequence[float]) -> tuple[float, float]:
    """(a, b) of values = c + a cos g + b sin g by least squares over the turn."""
    g = np.radians(np.asarray(angles_deg, float))
    m = np.column_stack([np.ones_like(g), np.cos(g), np.sin(g)])
    coef, *_ = np.linalg.lstsq(m, np.asarray(values, float), rcond=None)
    return float(coef[1]), float(coef[2])


def shim_arcsec(spindle_deg: Sequence[float], theodolite_arcsec: Sequence[Sequence[float]],
                at_deg: float = 0.0) -> tuple[float, float]:
    """The shim (x, y arcsec on the theodolite's axes) that puts mirror 1 on the spindle,
    made with the spindle at ``at_deg``."""
    g = math.radians(at_deg)
    out = []
    for axis in (0, 1):
        a, b = first_harmonic(spindle_deg, [p[axis] for p in theodolite_arcsec])
        out.append(-(a * math.cos(g) + b * math.sin(g)))
    return out[0], out[1]


def pickoff_translation_arcsec(a_cr: float, b_cr: float, slope_per_deg: float,
                               gamma_eq_deg: float, colatitude_sign: int
                               ) -> tuple[float, float]:
    """The translation of pickoff 1 along (c2, c3), arcsec, that cancels the first
    harmonic (a cos g + b sin g) of its count ratio over a spindle turn (module doc)."""
    return translation_arcsec(a_cr, b_cr, slope_per_deg,
                              gamma_eq_deg - colatitude_sign * 90.0)


def translation_arcsec(a_cr: float, b_cr: float, slope_per_deg: float, psi_deg: float
                       ) -> tuple[float, float]:
    """The translation of the pickoff along the spindle, along its two translation axes
    (the spindle frame's second and third), arcsec, with the spin axis at ``psi_deg``
    from the second towards the third at spindle angle 0 (module doc)."""
    big_a = -a_cr / slope_per_deg * 3600.0
    big_b = -b_cr / slope_per_deg * 3600.0
    psi = math.radians(psi_deg)
    d2 = big_a * math.cos(psi) + big_b * math.sin(psi)
    d3 = big_a * math.sin(psi) - big_b * math.cos(psi)
    return -d2, -d3
