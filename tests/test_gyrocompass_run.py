"""The whole CIGTF gyrocompassing accuracy test on the simulated station (report 001)."""

from __future__ import annotations

import json

import pytest

from laboratory.cigtf.gyrocompassing import run_gyrocompass_test
from procedures.runner import ProcedureError
from station.errors import InstrumentRefused
from station.racks.cigtf import CigtfRack, open_cigtf_drivers


def test_whole_test_recovers_truth_and_writes_record(tmp_path):
    res = run_gyrocompass_test(1, tmp_path)
    truth = res["truth"]["theta_arcsec"]
    for p in res["phases"]:
        assert abs(p["theta_arcsec"] - truth) < 4 * p["sigma_arcsec"], p
    assert [p["n"] for p in res["phases"]] == [25, 10]
    assert res["gsf"] == pytest.approx(4094.0, rel=0.02)  # S_T = 1 deg/hr/mA
    assert res["sim_seconds"] > 40 * 3600
    saved = json.loads((tmp_path / "gyrocompass.json").read_text())
    for k in ("gsf", "runs", "phases", "delta_arcsec", "Delta_arcsec", "tests", "truth",
              "sim_seconds", "wall_seconds"):
        assert k in saved
    assert set(saved["runs"][0]) >= {"phase", "theta_arcsec", "sigma_arcsec"}
    assert set(saved["phases"][0]) >= {"phase", "theta_arcsec", "sigma_arcsec", "s_arcsec", "n"}
    assert {t["dof"][0] for t in saved["tests"]} >= {24, 9}
    assert all(set(t) >= {"name", "statistic", "threshold", "dof", "significant"}
               for t in saved["tests"])
    assert (tmp_path / "gyrocompass.png").stat().st_size > 0
    for name in ("gyrocompass_runs", "gyrocompass_phases", "gyrocompass_conclusions",
                 "check_4.1", "check_4.3-R25", "check_4.4-R10"):
        assert (tmp_path / "sheets" / f"{name}.json").exists()


def test_silent_dvm_stops_with_named_instrument_and_step(tmp_path):
    # during the fourth or fifth operating run, after the set-up's 487 s (seed 2)
    stop_at = 487.0 + 2 * 3600 + 4 * 950.0

    def hook(rack: CigtfRack) -> None:
        def silence():
            yield rack.env.timeout(int(stop_at * 1e9))
            rack.dvm.silent = True
        rack.env.process(silence())

    with pytest.raises(ProcedureError) as ei:
        run_gyrocompass_test(2, tmp_path, rack_hook=hook)
    msg = str(ei.value)
    assert "dvm" in msg and "AVG?" in msg and "Chart 4.3-R" in msg and "step 4.2." in msg
    recs = [json.loads(x) for x in (tmp_path / "journal.jsonl").read_text().splitlines()]
    done = [r for r in recs if r.get("kind") == "step" and r["step"] == "5.2"]
    assert len(done) >= 3
    assert all("theta_arcsec" in r["reading"] for r in done)
    assert recs[-1]["kind"] == "failed" and "dvm" in recs[-1]["error"]


def test_fixture_refuses_bad_moves_and_reports_drive_fault():
    with CigtfRack(3) as rack:
        st = open_cigtf_drivers(rack)
        try:
            for cmd in ("MOVE V 1.5", "MOVE V 360", "TURN H 400", "MOVE X 10"):
                with pytest.raises(InstrumentRefused):
                    st.fixture.command(cmd)
            rack.fixture.fail_moves = True
            st.fixture.turn("V", 180)
            with pytest.raises(Exception, match="drive fault"):
                st.fixture.wait_hold()
            assert st.fixture.position() == (0, 0)
        finally:
            st.close()


def test_analysis_recomputed_from_the_journal(tmp_path):
    """`station gyrocompass-test --analyse DIR` gives the run's own phase analysis back."""
    from typer.testing import CliRunner

    from laboratory.cigtf.gyrocompassing import analyse_journal, run_gyrocompass_test
    from laboratory.cli import app

    res = run_gyrocompass_test(5, tmp_path)
    again = analyse_journal(tmp_path)
    assert again["phases"] == res["phases"]
    assert again["tests"] == res["tests"]
    assert again["truth"] == res["truth"]
    r = CliRunner().invoke(app, ["gyrocompass-test", "--analyse", str(tmp_path)])
    assert r.exit_code == 0 and "from the journal" in r.output


def test_fixture_failing_mid_test_stops_and_keeps_completed_runs(tmp_path):
    """A drive fault some hours in ends the test naming the fixture and the step."""
    import json

    from laboratory.cigtf.gyrocompassing import run_gyrocompass_test
    from procedures.runner import ProcedureError
    from sim.timebase import ticks

    def fail_later(rack):
        env = rack.world.env

        def fault():
            yield env.timeout(ticks(8 * 3600.0))
            rack.fixture.fail_moves = True

        env.process(fault())

    with pytest.raises(ProcedureError) as e:
        run_gyrocompass_test(2, tmp_path, rack_hook=fail_later)
    assert "fixture" in str(e.value) and "fault" in str(e.value).lower()
    recs = [json.loads(x) for x in (tmp_path / "journal.jsonl").read_text().splitlines()]
    done = [r for r in recs if r["kind"] == "step" and r["step"] == "5.2"]
    assert len(done) >= 5  # the runs completed before the fault are all in the journal
    assert recs[-1]["kind"] == "failed"


def test_config_sets_latitude_and_refuses_bad_fields(tmp_path):
    import math

    from station.config.cigtf import load_cigtf_params
    from station.config.isu import ConfigError

    f = tmp_path / "c.toml"
    f.write_text("[cigtf]\nlatitude_deg = 45.0\n")
    assert load_cigtf_params(f).latitude_deg == 45.0
    assert math.isclose(load_cigtf_params(None).latitude_deg, 32.89, abs_tol=0.01)
    f.write_text("[cigtf]\nlatitude = 45.0\n")
    with pytest.raises(ConfigError, match="cigtf.latitude"):
        load_cigtf_params(f)
