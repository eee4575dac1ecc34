"""The calibration day end to end: truth within the predicted error, determinism, partial
calibration, and clear stops on impossible inputs (kills and resumes: test_record_kills)."""

from __future__ import annotations

import json

import pytest
from rich.console import Console
from typer.testing import CliRunner

from laboratory.cli import app
from laboratory.compare import differences
from laboratory.isu.day import DayRequest, run_day
from laboratory.isu.spec import site_of
from laboratory.pytest_plugin import assert_within_sigma
from procedures.isu.calibration import NoiseSpec
from procedures.isu.computations import compute_calibration
from procedures.isu.day import DayData
from procedures.isu.plan import DayPlan
from procedures.journal import Journal
from procedures.runner import ProcedureError, Run
from station.clock import VirtualClock
from station.config.isu import load_config

QUIET = Console(quiet=True)
ROWS = 3 * 16 + 3 * 7  # Chart II-5: 16 gyro rows, 7 accelerometer rows, three instruments


@pytest.fixture(scope="module")
def day_a(tmp_path_factory):
    out = tmp_path_factory.mktemp("day_a")
    res = run_day(DayRequest(load_config(seed=2024), out, quiet=True), QUIET)
    return out, res


def test_every_estimate_within_4_sigma_of_truth(day_a):
    out, res = day_a
    rows = res["calibration"]
    assert len(rows) == ROWS
    assert {r["instrument"] for r in rows} == {f"gyro{k}" for k in (1, 2, 3)} | {
        f"accel{k}" for k in (1, 2, 3)}
    estimated = [r for r in rows if r["estimate"] is not None]
    assert len(estimated) == ROWS  # every row of Chart II-5 is determined by the full day
    for r in estimated:
        assert r["sigma"] is not None and r["sigma"] > 0, r
        assert abs(r["error"]) < 4 * r["sigma"], r
    saved = json.loads((out / "results.json").read_text())
    assert saved["seed"] == 2024 and saved["sim_seconds"] > 6 * 3600
    for name in ("survey_results", "resolver_settings", "counter_connections",
                 "counter_settings", "counter_outputs", "calibration_results", "check_I-1",
                 "check_II-6", "check_II-11", "check_II-15"):
        assert (out / "sheets" / f"{name}.json").exists(), name


def test_the_survey_records_the_configured_site(day_a):
    """Chart I-2 step 3: the survey sheet carries the site's g and Earth-rate parts exactly
    as the Site value gives them from the config."""
    out, _ = day_a
    sv = json.loads((out / "sheets" / "survey_results.json").read_text())
    site = site_of(load_config(seed=2024))
    assert (sv["g"], sv["omega_sin_lambda_deg_hr"], sv["omega_cos_lambda_deg_hr"]) == (
        site.g, site.omega_sin_lambda, site.omega_cos_lambda)
    # 42.36 deg N: below 45 deg the Earth rate leans more north than up
    assert 0.99 < site.g < 1.01 and site.omega_sin_lambda > site.omega_cos_lambda > 0


def test_same_seed_same_record_and_compare(day_a, tmp_path):
    out_a, _ = day_a
    run_day(DayRequest(load_config(seed=2024), tmp_path / "b", quiet=True), QUIET)
    assert differences(out_a, tmp_path / "b") == []
    runner = CliRunner()
    assert runner.invoke(app, ["compare", str(out_a), str(tmp_path / "b")]).exit_code == 0
    run_day(DayRequest(load_config(seed=2025), tmp_path / "c", quiet=True, plan=DayPlan(),
                       only=("II-11",)), QUIET)
    r = runner.invoke(app, ["compare", str(out_a), str(tmp_path / "c")])
    assert r.exit_code == 1 and "values differ" in r.output


def test_partial_calibration_gives_chart_ii16_set(station_lab, run_procedure):
    """Through the station's pytest plugin: a virtual ISU station, the day's run function,
    its record read back from the run directory."""
    rec = run_procedure("day", station_lab("isu", seed=7), only=("II-6", "II-11"))
    rows = rec.results["calibration"]
    got = {(r["instrument"], r["parameter"]) for r in rows if r["estimate"] is not None}
    gyro_ok = {"DeltaPhi", "G.B1", "G.B2", "G.B3", "R", "B_I", "B_O", "B_S", "C_II", "C_SS"}
    assert got == {(f"gyro{k}", p) for k in (1, 2, 3) for p in gyro_ok}
    assert rec.results == rec.returned and rec.run["status"] == "completed"
    assert "check_II-11" in rec.sheets and "check_II-7" not in rec.sheets
    for r in rows:
        if r["estimate"] is not None:
            assert_within_sigma(r["estimate"], r["truth"], r["sigma"], k=4,
                                name=f"{r['instrument']}.{r['parameter']}")


def test_counter_that_never_reaches_preset_stops_the_step(tmp_path):
    def dead_rotary_output(rack):
        rack.world.table.rotation_output = False  # the gate pulses never come

    with pytest.raises(ProcedureError) as e:
        run_day(DayRequest(load_config(seed=3), tmp_path, quiet=True, only=("II-6",)), QUIET,
                rack_hook=dead_rotary_output)
    msg = str(e.value)
    assert "Chart II-6, step 9/m1" in msg and "counter1" in msg and "no reply" in msg
    recs = [json.loads(x) for x in (tmp_path / "journal.jsonl").read_text().splitlines()]
    charts = {r.get("chart") for r in recs if r["kind"] == "step"}
    assert {"I-1", "I-2", "II-6"} <= charts  # everything done before the stop is kept
    assert recs[-1]["kind"] == "failed" and recs[-1]["step"] == "9/m1"


def test_computations_without_survey_name_the_chart(tmp_path):
    cfg = load_config()
    import simpy

    run = Run(VirtualClock(simpy.Environment()), Journal(tmp_path / "j.jsonl"))
    data = DayData(survey=None, s1=1e-6, f0=20000.0)
    with pytest.raises(ProcedureError) as e:
        compute_calibration(run, data, DayPlan(), NoiseSpec(),
                            site_of(cfg))
    assert "Chart II-15, step 1" in str(e.value) and "Survey Results Sheet" in str(e.value)


def test_a_day_stopped_in_its_alignments_leaves_no_staged_sheet(tmp_path, monkeypatch):
    """The calibration's sheets staged by the plot child while the alignments run
    (laboratory.record.SHEET_STAGE) are not left in the run directory of a day that stops
    there: the journal keeps what was done, and neither sheets/ nor a stage is written."""
    import time

    import laboratory.isu.day as day_module

    def stopped_alignments(*args, **kwargs):
        for _ in range(500):  # until the child has staged the calibration's sheets
            if any(p.name.startswith(".sheets-stage.") for p in tmp_path.iterdir()):
                break
            time.sleep(0.01)
        raise ProcedureError("III-2", "1", "mirror alignment", "stopped for the test")

    monkeypatch.setattr(day_module, "day_alignments", stopped_alignments)
    with pytest.raises(ProcedureError):
        run_day(DayRequest(load_config(seed=5), tmp_path, quiet=True,
                           only=("II-6", "II-11")), QUIET)
    names = {p.name for p in tmp_path.iterdir()}
    assert "journal.jsonl" in names and "sheets" not in names
    assert not [n for n in names if n.startswith(".sheets-stage.")]
