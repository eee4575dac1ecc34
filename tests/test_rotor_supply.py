"""The CIGTF gyro power supply's rotor voltage (report 001 section 1's parameter variation,
issue 20): set by the procedure through ``VOLT`` before turn-on, it gives the simulator the
same gyro, and so the same truth, as configuring ``rotor_voltage_v``."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from laboratory.cigtf.gyrocompassing import analyse_journal, run_gyrocompass_test
from laboratory.cigtf.variation import true_theta
from procedures.cigtf.procedure import TestPlan as CigtfPlan
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


def test_run_at_32_volts_by_command_has_the_configured_truth(tmp_path):
    """A whole test whose plan sets 32 V through the supply: the step records the supply's
    reading, and the run's truth is that of the gyro configured at 32 V; its theta lies
    within 4 sigma of it in each phase."""
    plan = CigtfPlan(pretest_setup=False, rotor_voltage_v=32.0, operating_runs=3,
                     shutdown_runs=2)  # a short test: the truth is the point
    res = run_gyrocompass_test(4, tmp_path / "r", params=MAGNETIC, plan=plan)
    truth = true_theta(4, replace(MAGNETIC, rotor_voltage_v=32.0), 0)
    assert res["truth"]["theta_arcsec"] == pytest.approx(
        CigtfWorld(4, replace(MAGNETIC, rotor_voltage_v=32.0)).truth_theta_arcsec(), abs=1e-9)
    assert abs(truth - res["truth"]["theta_arcsec"]) < 0.5  # eq. 26 against the exact sum
    sheet = json.loads((tmp_path / "r" / "sheets" / "check_4.0.json").read_text())
    step = next(s for s in sheet["steps"] if s["number"] == "4.0.0")
    assert step["reading"] == {"rotor_voltage_v": 32.0}
    for ph in res["phases"]:
        assert abs(ph["theta_arcsec"] - res["truth"]["theta_arcsec"]) < 4 * ph["sigma_arcsec"]
    # --analyse rebuilds the truth with the supply the journal recorded, not the params'
    again = analyse_journal(tmp_path / "r", params=MAGNETIC)
    assert again["truth"]["theta_arcsec"] == pytest.approx(res["truth"]["theta_arcsec"],
                                                           abs=1e-9)
