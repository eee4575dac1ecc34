"""The procedure's nominal mounting geometry (procedures/esg/geometry.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from procedures.esg import geometry as geo
from procedures.esg.acquisition import (
    design_colatitude_deg,
    design_slope_per_deg,
    equal_ratio_direction,
)


def test_spindle_direction_and_case_axes_at_zero():
    r = geo.r_lc(0.0, 0.0, 0.0)
    assert np.allclose(r[:, 0], [0, 1, 0]) and np.allclose(r[:, 1], [0, 0, 1])
    assert np.allclose(r[:, 2], [1, 0, 0])
    a, e = 30.0, 20.0
    u = geo.r_lc(a, e, 77.0)[:, 0]
    want = [math.sin(math.radians(a)) * math.cos(math.radians(e)),
            math.cos(math.radians(a)) * math.cos(math.radians(e)), math.sin(math.radians(e))]
    assert np.allclose(u, want)
    # a positive spindle angle carries c2 towards c3
    r1 = geo.r_lc(0.0, 0.0, 10.0)
    assert r1[:, 1] @ r[:, 2] > 0


@pytest.mark.parametrize("d", [[1, 1, 1], [-1, -1, -1], [0, 0.8, 0.6], [0.3, -0.5, 0.8]])
@pytest.mark.parametrize("s", [[0, 0.98, -0.19], [0.1, 0.7, 0.7], [0, 0.2, -0.98]])
def test_point_case_puts_d_on_s(d, s):
    a, e, g = geo.point_case(d, s)
    assert abs(e) <= 90.0
    assert np.allclose(geo.r_lc(a, e, g) @ geo.unit(d), geo.unit(s), atol=1e-12)


def test_drift_equilibrium_is_steady():
    lat, k = 44.98, 12.7
    s = geo.drift_equilibrium(lat, k)
    w = geo.EARTH_RATE_DEG_HR * np.array([0, math.cos(math.radians(lat)),
                                         math.sin(math.radians(lat))])
    assert np.linalg.norm(np.cross(s, w + k * np.array([0, 0, -1.0]))) < 1e-12
    # on the polar axis the unbalance alone drifts s west at k cos(lat): k comes back
    epa = geo.polar_axis(lat)
    east = np.cross(epa, k * np.array([0, 0, -1.0]))[0]
    assert geo.unbalance_k_from_east_drift(east, epa) == pytest.approx(k)


def test_design_pattern_inverse_and_slope():
    for th in (46.0, 60.0, 90.0, 120.0, 134.0):
        h = 1e-4
        # forward map: the count ratio whose design colatitude is th
        lo, hi = 0.0, 1.0
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if design_colatitude_deg(mid, 56.0) > th:
                lo = mid
            else:
                hi = mid
        cr = 0.5 * (lo + hi)
        assert design_colatitude_deg(cr, 56.0) == pytest.approx(th, abs=1e-9)
        num = (design_colatitude_deg(cr + h, 56.0)
               - design_colatitude_deg(cr - h, 56.0)) / (2 * h)
        assert 1.0 / num == pytest.approx(design_slope_per_deg(th, 56.0), rel=1e-4)
    # count ratio above one half on the colatitudes below 90 deg (Table B-1: 50 deg <-> 0.70)
    assert design_colatitude_deg(0.70, 56.0) < 90.0
    assert design_slope_per_deg(90.0, 56.0) == pytest.approx(
        -1.0 / math.tan(math.radians(56.0)) / math.pi * math.pi / 180.0, rel=1e-6)


def test_equal_ratio_direction_with_the_measured_mirror_angle():
    d = equal_ratio_direction(89.0 + 56 / 60 + 5 / 3600)
    g = math.radians(89.0 + 56 / 60 + 5 / 3600)
    p = np.array([[1, 0, 0], [math.cos(g), math.sin(g), 0], [0, 0, 1.0]])
    cos = p @ d
    assert np.ptp(cos) < 1e-12
    # from the Gram matrix: cos(theta*) = 1 / sqrt(1' G^-1 1), G = P P'
    gram = p @ p.T
    c_star = 1.0 / math.sqrt(np.ones(3) @ np.linalg.solve(gram, np.ones(3)))
    assert cos[0] == pytest.approx(c_star, abs=1e-12)
    assert math.degrees(math.acos(cos[0])) == pytest.approx(54.7202, abs=2e-4)
