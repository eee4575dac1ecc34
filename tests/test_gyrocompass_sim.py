"""Fixture and SDF gyro models against eq. 26 of report 001 Appendix II."""

from __future__ import annotations

import math

import numpy as np
import pytest

from procedures.cigtf.analysis import run_values
from procedures.cigtf.scale import (
    ARCSEC_PER_RAD,
    REPORT_LATITUDE_DEG,
    gsf_from_turn,
)
from sim.cigtf.fixture import GyrocompassFixture, Misalignments, q_ge
from sim.cigtf.sdf_gyro import DriftModel, Dynamics, SdfGyro, steady_current
from sim.units import ARCSEC, EARTH_RATE, deg_per_hr

LAT = math.radians(REPORT_LATITUDE_DEG)
MODEL = DriftModel(s_t=deg_per_hr(10.0) / 1e-3, d_f=deg_per_hr(1.5), d_i=deg_per_hr(0.4),
                   d_o=deg_per_hr(-0.7), d_s=deg_per_hr(0.3), d_ii=deg_per_hr(0.05),
                   d_ss=deg_per_hr(0.02), d_io=deg_per_hr(0.1), d_is=deg_per_hr(0.03),
                   d_os=deg_per_hr(0.25))
MIS = Misalignments(*(ARCSEC * x for x in (3.0, 2.0, -4.0, 1.5, -2.5, 5.0, 40.0, -30.0, 25.0)))


def _orientation_currents(m: Misalignments, eps: float, beta: float, eta: float):
    """Currents in orientations 1-4 reached by 180 deg turns with errors (App. II 2.2-2.5)."""
    pi = math.pi
    angles = [(0.0, 0.0), (pi + eps, 0.0), (pi + eps, pi + beta), (2 * pi + eps + eta, pi + beta)]
    return [steady_current(MODEL, q_ge(m, v, h), LAT) for v, h in angles]


def _eq26_theta(m: Misalignments, eps: float, eta: float) -> float:
    """theta (arcsec) = -(a+d)' from eq. 27 rearranged; what the four orientations leave."""
    ws, wc = EARTH_RATE * math.sin(LAT), EARTH_RATE * math.cos(LAT)
    rhs = (-4 * m.b * MODEL.d_i + 4 * m.c * MODEL.d_os - 4 * m.b * ws + 4 * (m.a + m.d) * wc
           + (3 * eps + eta) * wc)
    return -rhs / (4 * wc) * ARCSEC_PER_RAD


def _gsf() -> float:
    i1 = steady_current(MODEL, q_ge(Misalignments(), 0.0, 0.0), LAT)
    i1t = steady_current(MODEL, q_ge(Misalignments(), math.radians(1.0), 0.0), LAT)
    return gsf_from_turn(i1, i1t)


def _theta(m: Misalignments, eps=0.0, beta=0.0, eta=0.0) -> float:
    return run_values([[x, x] for x in _orientation_currents(m, eps, beta, eta)], _gsf()).theta


def test_gsf_of_model_matches_scale_factor():
    # 900/(I1 - I1') against arcsec/(4 omega_EH) * S_T; eq. 10 takes sin(1 deg) as 1 deg
    want = ARCSEC_PER_RAD * MODEL.s_t / (4 * EARTH_RATE * math.cos(LAT))
    one = math.radians(1.0)
    assert _gsf() == pytest.approx(want * one / math.sin(one), rel=1e-6)


def test_four_orientation_theta_equals_eq26():
    assert _theta(MIS) == pytest.approx(_eq26_theta(MIS, 0.0, 0.0), abs=2e-3)


def test_gyro_and_output_axis_misalignments_cancel():
    only_hije = Misalignments(e=MIS.e, f=MIS.f, h=MIS.h, i=MIS.i, j=MIS.j)
    assert _theta(only_hije) == pytest.approx(0.0, abs=2e-3)


@pytest.mark.parametrize("eps,beta,eta", [(0.5, 0.0, 0.0), (0.0, 0.5, 0.0), (0.0, 0.0, 0.5),
                                          (0.4, -0.3, -0.2)])
def test_turn_errors_enter_as_three_epsilon_plus_eta(eps, beta, eta):
    e, b, n = (x * ARCSEC for x in (eps, beta, eta))
    got = _theta(MIS, e, b, n) - _theta(MIS)
    assert got == pytest.approx(-(3 * eps + eta) / 4, abs=2e-3)


def test_fixture_detents_repeat_within_spec():
    fx = GyrocompassFixture(MIS, seed=0)
    fx.move_to(180, 0)
    v1 = fx.angles()[0]
    fx.move_to(0, 0)
    fx.move_to(180, 0)
    v2 = fx.angles()[0]
    assert abs(v1 - math.pi) < 1.0 * ARCSEC
    assert abs(v2 - v1) < 0.6 * ARCSEC


def test_gyro_settles_after_move_and_turn_on_shift():
    dyn = Dynamics(settle_tau=10.0, turn_on_sd=deg_per_hr(0.01))
    g = SdfGyro(MODEL, LAT, dyn, seed=7)
    q1, q2 = q_ge(MIS, 0.0, 0.0), q_ge(MIS, math.pi, 0.0)
    g.power_on(0.0, q1)
    i_a = g.current(100.0)
    g.moved(100.0, q2)
    assert g.current(100.0) == pytest.approx(i_a)
    assert g.current(300.0) == pytest.approx(steady_current(MODEL, q2, LAT)
                                             + g.extra_drift(300.0) / MODEL.s_t, rel=1e-9)
    g.power_off()
    assert g.current(400.0) == 0.0
    g.power_on(500.0, q1)
    assert g.extra_drift(600.0) != pytest.approx(0.0, abs=1e-15)


def test_walk_is_independent_of_query_order():
    dyn = Dynamics(drift_walk=deg_per_hr(0.001) / 60.0)
    a, b = SdfGyro(MODEL, LAT, dyn, 3), SdfGyro(MODEL, LAT, dyn, 3)
    q = q_ge(MIS, 0.0, 0.0)
    a.power_on(0.0, q)
    b.power_on(0.0, q)
    b.current(10_000.0)
    assert a.current(5_000.0) == b.current(5_000.0)


def test_currents_at_many_times_are_current_at_each():
    """The DVM's Simpson nodes in one evaluation give the scalar model's current at each
    node (settling, warm-up, turn-on shift and walk all on), including before turn-on."""
    dyn = Dynamics(settle_tau=15.0, warmup_amplitude=deg_per_hr(0.02), warmup_tau=900.0,
                   drift_walk=deg_per_hr(0.001) / 60.0, turn_on_sd=deg_per_hr(0.01))
    g, h = SdfGyro(MODEL, LAT, dyn, 11), SdfGyro(MODEL, LAT, dyn, 11)
    tt = np.linspace(3_000.0, 3_010.0, 21)
    assert not g.currents(tt).any()  # off: zero
    for s in (g, h):
        s.power_on(1_000.0, q_ge(MIS, 0.0, 0.0))
        s.moved(2_995.0, q_ge(MIS, math.pi, 0.0))
    many = g.currents(tt)
    one = np.array([h.current(float(t)) for t in tt])
    np.testing.assert_allclose(many, one, rtol=1e-14, atol=0.0)
    assert np.ptp(many) > 0.0  # the settling and the walk move it across the aperture
