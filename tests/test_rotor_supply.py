"""The CIGTF gyro power supply's rotor voltage (report 001 section 1's parameter variation,
issue 20): set by the procedure through ``VOLT`` before turn-on, it gives the simulator the
same gyro, and so the same truth, as configuring ``rotor_voltage_v``."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from laboratory.cigtf.gyrocompassing import data_from_records
from laboratory.cigtf.variation import true_theta
from procedures.cigtf.procedure import TestPlan as CigtfPlan
from procedures.cigtf.procedure import warm_up
from procedures.journal import Journal
from procedures.runner import Run
from sim.cigtf.sdf_gyro import steady_current
from sim.cigtf.world import CigtfParams, CigtfWorld
from station.errors import DriverError
from station.racks.cigtf import CigtfRack, open_cigtf_drivers

MAGNETIC = replace(CigtfParams(), magnetic_drift_deg_hr_per_gauss=0.02, pretest_setup=False)


def test_volt_command_gives_the_configured_gyro():
    rack = CigtfRack(3, MAGNETIC)
    with rack:
        st = open_cigtf_drivers(rack)
        assert st.power.rotor_voltage() == 26.0
        st.power.set_rotor_voltage(32.0)
        assert st.power.rotor_voltage() == 32.0
        configured = CigtfWorld(3, replace(MAGNETIC, rotor_voltage_v=32.0))
        assert rack.world.model == configured.model
        assert rack.world.truth_theta_arcsec() == configured.truth_theta_arcsec()
        assert rack.world.truth_theta_arcsec() != CigtfWorld(3, MAGNETIC).truth_theta_arcsec()


def test_volt_refused_with_the_gyro_on_and_out_of_range():
    rack = CigtfRack(3, MAGNETIC)
    with rack:
        st = open_cigtf_drivers(rack)
        with pytest.raises(DriverError, match="10..40 V"):
            st.power.set_rotor_voltage(45.0)
        st.power.on()
        with pytest.raises(DriverError, match="turn the gyro power off first"):
            st.power.set_rotor_voltage(30.0)
        assert st.power.rotor_voltage() == 26.0


def test_turn_on_at_32_volts_by_command_has_the_configured_truth(tmp_path):
    """The procedure's step 4.0.0 sets 32 V through the supply before turn-on: the gyro then
    running is the one configured at 32 V (same eq. 26 truth and steady current), the step
    records the supply's reading, and a journal's analysis takes the voltage from it. (The
    whole test by command: tests/test_gyrocompass_variation.py's rotor-voltage study.)"""
    plan = CigtfPlan(pretest_setup=False, rotor_voltage_v=32.0, initial_warmup_s=60.0)
    configured = CigtfWorld(4, replace(MAGNETIC, rotor_voltage_v=32.0))
    rack = CigtfRack(4, MAGNETIC)
    with rack:
        st = open_cigtf_drivers(rack)
        journal = tmp_path / "journal.jsonl"
        warm_up(st, Run(st.clock, Journal(journal)), plan)
        w = rack.world
        assert w.truth_theta_arcsec() == pytest.approx(configured.truth_theta_arcsec(),
                                                       abs=1e-12)
        q = w.fixture.q_ge()
        assert w.gyro._steady(q) == steady_current(configured.model, q, w.latitude)
    assert abs(true_theta(4, replace(MAGNETIC, rotor_voltage_v=32.0), 0)
               - configured.truth_theta_arcsec()) < 0.5  # eq. 26 against the exact sum
    records = [json.loads(x) for x in journal.read_text().splitlines()]
    step = next(r for r in records if r.get("step") == "4.0.0")
    assert step["reading"] == {"rotor_voltage_v": 32.0}
    data, _ = data_from_records(records)
    assert data.rotor_voltage_v == 32.0
