"""The pre-test set-up of report 001 section 4.1 (procedures/cigtf/setup.py) against the
simulator's truth: levels read at vertical 0 and 180 deg, the autocollimator at horizontal
0 and 180 deg, screws and base adjusted until within 0.5 arcsec, displays at 0 0."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from procedures.cigtf.setup import SetupPlan, pretest_setup
from procedures.journal import Journal
from procedures.runner import Run
from sim.cigtf.world import CigtfParams, CigtfWorld, draw_misalignments
from sim.units import ARCSEC, to_arcsec
from station.errors import InstrumentRefused
from station.racks.cigtf import CigtfRack, open_cigtf_drivers


def _set_up(seed: int, tmp_path: Path) -> tuple[dict, CigtfRack, Run]:
    rack = CigtfRack(seed)
    st = open_cigtf_drivers(rack)
    run = Run(st.clock, Journal(tmp_path / f"journal-{seed}.jsonl"))
    return pretest_setup(st, run), rack, run


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5, 6])
def test_setup_leaves_b_c_and_north_within_their_sigma_of_the_truth(seed, tmp_path):
    installed = draw_misalignments(CigtfParams(), seed)
    res, rack, run = _set_up(seed, tmp_path)
    m = rack.world.misalignments
    truth = {"b": to_arcsec(m.b), "c": to_arcsec(m.c), "north": to_arcsec(m.a + m.d)}
    tol = SetupPlan().tolerance_arcsec
    for k, t in truth.items():
        est, sd = res[f"{k}_arcsec"], res[f"{k}_sigma_arcsec"]
        assert 0.02 < sd < 0.3, k  # the levels' and autocollimator's noise over 10 + 10
        assert abs(est - t) <= 4.0 * sd, (k, est, t, sd)
        assert abs(t) <= tol + 4.0 * sd, k  # levelled and aligned "less than 1 sec"
    # the fixture stood tens of arcsec off level and minutes off north: it was adjusted
    assert max(abs(installed.b), abs(installed.c)) > 5 * ARCSEC and res["level_rounds"] >= 3
    assert abs(installed.a) > 5 * ARCSEC and res["azimuth_rounds"] >= 3
    assert m.d == installed.d and m.h == installed.h  # the set-up leaves the rest alone
    sheet = run.check_sheets["4.1-S"]
    assert [s.number for s in sheet.steps] == ["4.1.S1", "4.1.S2", "4.1.S3"]
    assert sheet.steps[2].reading == {"vertical_deg": 0, "horizontal_deg": 0}
    rounds = sheet.steps[0].reading["rounds"]
    # the half-sum of the 0 and 180 deg level readings is the level's zero (truth: offset)
    off = to_arcsec(rack.world.aids.level_offsets[0])
    assert rounds[-1]["ew_offset_arcsec"] == pytest.approx(off, abs=0.5)
    rack.close()


def test_old_behaviour_draws_a_b_c_at_level_sd_and_skips_the_setup(tmp_path):
    from laboratory.cigtf.gyrocompassing import run_gyrocompass_test
    from procedures.cigtf.procedure import TestPlan

    p = replace(CigtfParams(), pretest_setup=False)
    w = CigtfWorld(7, p)
    assert to_arcsec(abs(w.misalignments.b)) < 15.0  # 3 arcsec sd
    plan = TestPlan(operating_runs=2, shutdown_runs=2, pretest_setup=False)
    res = run_gyrocompass_test(7, tmp_path / "old", params=p, plan=plan)
    assert res["setup"] is None
    assert not (tmp_path / "old" / "sheets" / "gyrocompass_setup.json").exists()


def test_setup_record_in_a_run_and_in_its_reanalysis(tmp_path):
    """gyrocompass.json and sheets/gyrocompass_setup.json hold the residuals with the truth;
    --analyse rebuilds the same truth (the twin rack is set up as the run was)."""
    from laboratory.cigtf.gyrocompassing import analyse_journal, run_gyrocompass_test
    from procedures.cigtf.procedure import TestPlan

    plan = TestPlan(operating_runs=2, shutdown_runs=2)
    res = run_gyrocompass_test(4, tmp_path, plan=plan)
    rows = {r["parameter"]: r for r in res["setup"]}
    assert set(rows) == {"b", "c", "a + d"}
    assert all(r["truth_check"] == "within 4 sigma" for r in rows.values())
    assert res["truth"]["north_arcsec"] == pytest.approx(-rows["a + d"]["truth"])
    sheet = json.loads((tmp_path / "sheets" / "gyrocompass_setup.json").read_text())
    assert sheet == res["setup"]
    assert (tmp_path / "sheets" / "check_4.1-S.json").is_file()
    assert analyse_journal(tmp_path)["truth"] == res["truth"]


def test_setup_aids_refuse_while_moving_and_outside_the_field():
    rack = CigtfRack(3)
    st = open_cigtf_drivers(rack)
    try:
        st.fixture.move("V", 180)
        with pytest.raises(InstrumentRefused, match="busy"):
            st.aids.levels()
        st.fixture.wait_hold()
        with pytest.raises(InstrumentRefused, match="outside the autocollimator's field"):
            st.aids.azimuth()  # the horizontal axis points south
        for cmd in ("TILT XY 1", "TILT EW 601", "BASE 1e9", "BASE nan"):
            with pytest.raises(InstrumentRefused):
                st.aids.command(cmd)
    finally:
        st.close()
