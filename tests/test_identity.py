"""The run's identity (run.json, config.toml), the sheets' headers and --operator."""

from __future__ import annotations

import hashlib
import json

import pytest
from typer.testing import CliRunner

import laboratory.isu.day as day_mod
from instruments.isu.table_controller import TableController
from laboratory.cli import app
from laboratory.compare import differences
from laboratory.identity import identified, isu_config, operator_name, to_toml
from laboratory.isu.day import DayRequest, run_day
from station.config.file import ConfigError
from station.config.identity import load_identity
from station.config.isu import load_config

SHORT = ("--only", "II-11", "--positions", "7", "--quiet")


@pytest.fixture
def cli(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    return lambda *args: runner.invoke(app, [str(a) for a in args])


def _run_json(d):
    return json.loads((d / "run.json").read_text())


def _journal(d):
    return [json.loads(x) for x in (d / "journal.jsonl").read_text().splitlines()]


def test_a_short_day_writes_run_json_running_then_completed(tmp_path, monkeypatch):
    seen = {}
    measure = day_mod.measure_day

    def peek(*a, **k):
        seen.update(_run_json(out))
        return measure(*a, **k)

    monkeypatch.setattr(day_mod, "measure_day", peek)
    monkeypatch.setenv("STATION_OPERATOR", "J. Doe")
    out = tmp_path / "D"
    cfg = load_config(seed=5)
    run_day(DayRequest(cfg, out, only=("II-11",), positions=(7,), quiet=True))
    assert seen["status"] == "running" and seen["ended_utc"] is None
    assert seen["exit_code"] is None and seen["verdict"] is None
    rec = _run_json(out)
    assert rec["status"] == "completed" and rec["exit_code"] == 0 and rec["reason"] is None
    assert rec["run_uid"] == seen["run_uid"] and len(rec["run_uid"]) == 32
    assert (rec["laboratory"], rec["command"], rec["seed"], rec["argv"]) == ("isu", "day", 5, [])
    assert rec["operator"] == "J. Doe" and rec["station_id"] == "ERC-GL-ISU-1"
    assert rec["unit"]["isu"] == "ISU-000-001" and rec["unit"]["accel3"] == "ACCEL-003"
    assert rec["ended_utc"] >= rec["started_utc"]
    starts = [r for r in _journal(out) if r.get("event") == "start"]
    assert starts[0]["run_uid"] == rec["run_uid"]
    # the resolved config: its digest, and read back it is the same config
    raw = (out / "config.toml").read_bytes()
    assert rec["config_file"] == "config.toml"
    assert rec["config_digest"] == hashlib.sha256(raw).hexdigest()
    assert load_config(out / "config.toml") == cfg
    # the sheets' headers
    res = json.loads((out / "sheets" / "calibration_results.json").read_text())
    assert res["header"] == {
        "experiment": "calibration day (station day)", "principal_operator": "J. Doe",
        "date": rec["started_utc"][:10], "identification": "ISU-000-001",
        "sheets_used": ["Chart I-3", "Chart II-1", "Chart II-3", "Chart II-4"],
        "special_procedures": None}
    survey = json.loads((out / "sheets" / "survey_results.json").read_text())
    assert survey["header"]["sheets_used"] == []
    check = json.loads((out / "sheets" / "check_I-1.json").read_text())
    assert check["header"]["principal_operator"] == "J. Doe"


def test_a_config_with_faults_reads_back_the_same(tmp_path):
    cfg = load_config(overrides={"faults": {"table": {"stall_axis": 2}},
                                 "identity": {"unit": {"gyro2": "G-77"}}})
    f = tmp_path / "c.toml"
    f.write_text(to_toml(isu_config(cfg)))
    assert load_config(f) == cfg


def test_a_stopped_run_records_chart_step_and_reason_and_resume_keeps_its_uid(
        cli, tmp_path, monkeypatch):
    init = TableController.__init__

    def open_interlock(self, *args, **kwargs):
        init(self, *args, **kwargs)
        self.interlock_closed = False

    monkeypatch.setattr(TableController, "__init__", open_interlock)
    out = tmp_path / "D"
    r = cli("day", "--seed", 3, "--out", out, *SHORT, "--operator", "A. Tester")
    assert r.exit_code == 1, r.output
    rec = _run_json(out)
    assert (rec["status"], rec["chart"], rec["step"], rec["exit_code"]) == (
        "stopped", "I-1", "6", 1)
    assert rec["reason"].startswith("Chart I-1, step 6 (Table interlock closed")
    assert "\n" not in rec["reason"] and rec["ended_utc"] is not None
    assert rec["operator"] == "A. Tester" and rec["argv"]
    monkeypatch.setattr(TableController, "__init__", init)
    r = cli("day", "--resume", out, "--quiet")
    assert r.exit_code == 0, r.output
    again = _run_json(out)
    assert again["run_uid"] == rec["run_uid"] and again["started_utc"] == rec["started_utc"]
    assert again["operator"] == "A. Tester"
    assert (again["status"], again["chart"], again["step"], again["reason"]) == (
        "completed", None, None, None)
    starts = [x for x in _journal(out) if x.get("event") == "start"]
    assert {s["run_uid"] for s in starts} == {rec["run_uid"]}  # a replay adds no note


def test_an_interrupted_run_is_aborted_with_its_class(tmp_path, monkeypatch):
    def interrupt(*a, **k):
        raise KeyboardInterrupt("operator pressed ^C")

    monkeypatch.setattr(day_mod, "measure_day", interrupt)
    out = tmp_path / "D"
    with pytest.raises(KeyboardInterrupt):
        run_day(DayRequest(load_config(), out, only=("II-11",), positions=(7,), quiet=True))
    rec = _run_json(out)
    assert (rec["status"], rec["exit_code"]) == ("aborted", 130)
    assert rec["reason"] == "KeyboardInterrupt: operator pressed ^C"


def test_operator_option_then_environment_then_login(cli, tmp_path, monkeypatch):
    monkeypatch.setenv("STATION_OPERATOR", "env op")
    assert operator_name("  Given   Name ") == "Given Name"
    assert operator_name(None) == "env op"
    monkeypatch.delenv("STATION_OPERATOR")
    monkeypatch.setenv("LOGNAME", "loginname")
    assert operator_name(None) == "loginname"
    monkeypatch.setenv("STATION_OPERATOR", "env op")
    r = cli("day", "--out", tmp_path / "A", *SHORT)
    assert r.exit_code == 0, r.output
    assert _run_json(tmp_path / "A")["operator"] == "env op"


def test_compare_ignores_the_run_specific_stamps(tmp_path):
    for d in ("A", "B"):
        run_day(DayRequest(load_config(), tmp_path / d, only=("II-11",), positions=(7,),
                           quiet=True))
    assert _run_json(tmp_path / "A")["run_uid"] != _run_json(tmp_path / "B")["run_uid"]
    assert differences(tmp_path / "A", tmp_path / "B") == []


def test_cigtf_and_esg_identity_sections(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text('[cigtf]\nlatitude_deg = 30.0\n[identity]\nstation_id = "X"\n'
                 '[identity.unit]\ngyro = "SN-9"\n')
    ident = load_identity(f, "CIGTF")
    assert (ident.station_id, ident.unit.model_dump()) == ("X", {"gyro": "SN-9"})
    f.write_text('[identity.unit]\nrotr = "R1"\n')
    with pytest.raises(ConfigError, match=r"identity\.unit\.rotr: unknown field"):
        load_identity(f, "ESG")
    f.write_text('[identity]\nstation_id = ""\n')
    with pytest.raises(ConfigError, match=r"identity\.station_id"):
        load_identity(f, "ESG")


def test_a_cigtf_run_writes_its_section_and_identity(cli, tmp_path):
    f = tmp_path / "c.toml"
    f.write_text('[identity.unit]\ngyro = "SN-9"\n')
    out = tmp_path / "G"
    r = cli("gyrocompass-test", "--out", out, "--config", f, "--operator", "Op")
    assert r.exit_code == 0, r.output
    rec = _run_json(out)
    assert (rec["laboratory"], rec["command"], rec["unit"], rec["operator"]) == (
        "cigtf", "gyrocompass-test", {"gyro": "SN-9"}, "Op")
    assert load_identity(out / "config.toml", "CIGTF").unit.gyro == "SN-9"
    assert [r for r in _journal(out) if r.get("event") == "start"][0]["run_uid"] == rec["run_uid"]


def test_identified_closes_a_failed_verdict_as_completed(tmp_path):
    from station.errors import StopError

    class VerdictFailed(StopError):
        exit_code = 3

    with pytest.raises(VerdictFailed), identified(tmp_path, "isu", "day", 1, {"seed": 1},
                                                  "S", {"isu": "U"}):
        raise VerdictFailed("verdict: FAIL gyro1:R")
    rec = _run_json(tmp_path)
    assert (rec["status"], rec["exit_code"]) == ("completed", 3)
