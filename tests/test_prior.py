"""Carry-forward across days: `--prior` gives a partial calibration the full Chart II-5 set
from an earlier sheet (each row citing it), refused for another unit or a stale run;
`--survey` reuses an earlier Survey Results Sheet instead of Chart I-2."""

from __future__ import annotations

import datetime as dt
import json
import subprocess
import sys

import pytest
from rich.console import Console

from laboratory.isu.day import DayRequest, run_day
from laboratory.isu.prior import PriorRefused, carried_sheets
from station.config.isu import load_config

QUIET = Console(quiet=True)
ROWS = 3 * 16 + 3 * 7


@pytest.fixture(scope="module")
def day1(tmp_path_factory):
    out = tmp_path_factory.mktemp("prior") / "day1"
    run_day(DayRequest(load_config(seed=11), out, quiet=True, align=False), QUIET)
    return out


def _uid(run_dir):
    return json.loads((run_dir / "run.json").read_text())["run_uid"]


def test_partial_calibration_with_prior_gives_full_chart_ii5(day1, tmp_path):
    out = tmp_path / "day2"
    res = run_day(DayRequest(load_config(seed=12), out, quiet=True, align=False,
                             only=("II-11",), prior=day1), QUIET)
    rows = res["calibration"]
    assert len(rows) == ROWS
    source = f"Chart II-5 of run {_uid(day1)} (day1)"
    measured = {"R", "B_I", "B_O", "B_S", "C_II", "C_SS"}
    prior = {(r["instrument"], r["parameter"]): r for r in json.loads(
        (day1 / "sheets" / "calibration_results.json").read_text())["rows"]}
    today = []
    for r in rows:
        assert r["estimate"] is not None and r["sigma"] > 0, r
        assert abs(r["error"]) < 4 * r["sigma"], r
        assert source in r["note"], r
        key = (r["instrument"], r["parameter"])
        if r["instrument"].startswith("gyro") and r["parameter"] in measured:
            assert r["note"].startswith("prerequisites G.B1/DeltaPhi")
            today.append(r["estimate"] != prior[key]["estimate"])
        else:
            assert r["note"] == f"carried forward from {source}"
            assert (r["estimate"], r["sigma"]) == (prior[key]["estimate"], prior[key]["sigma"])
    # measured today (a half-difference of counts may repeat exactly: one did, gyro1 B_O)
    assert len(today) == 18 and sum(today) >= 15
    sheet = json.loads((out / "sheets" / "calibration_results.json").read_text())
    assert sheet["header"]["sheets_used"][-1] == source
    ii15 = json.loads((out / "sheets" / "check_II-15.json").read_text())
    steps = {s["number"]: s for s in ii15["steps"]}
    assert steps["3"]["reading"]["prerequisites"]["source"] == source
    assert steps["7"]["reading"]["source"] == source  # last D1 D3: no position 13, 14
    assert set(steps["7"]["reading"]) == {"1", "2", "3", "source"}
    assert len(steps["8"]["reading"]["carried"]["rows"]) == ROWS - 3 * len(measured)


def test_prior_of_another_unit_or_too_old_is_refused(day1, tmp_path):
    cfg = load_config(seed=12)
    other = load_config(seed=12, overrides={"identity": {"unit": {"gyro2": "GYRO-XYZ"}}})
    with pytest.raises(PriorRefused, match=r"--prior: unit gyro2 of .* is 'GYRO-002', the "
                       r"config's \[identity.unit\] gyro2 is 'GYRO-XYZ'"):
        carried_sheets(other, day1, None)
    started = dt.datetime.fromisoformat(json.loads((day1 / "run.json").read_text())
                                        ["started_utc"])
    later = started + dt.timedelta(days=31)
    with pytest.raises(PriorRefused, match=r"--survey: .* started 31.0 days ago, more than "
                       r"\[identity\] max_prior_age_days = 30"):
        carried_sheets(cfg, None, day1, now=later)
    patient = load_config(seed=12, overrides={"identity": {"max_prior_age_days": 40}})
    assert carried_sheets(patient, day1, day1, now=later).prior is not None


def test_survey_reused_instead_of_chart_i2(day1, tmp_path):
    out = tmp_path / "day3"
    res = run_day(DayRequest(load_config(seed=11), out, quiet=True, align=False,
                             only=("II-11",), prior=day1, survey=day1), QUIET)
    assert not (out / "sheets" / "check_I-2.json").exists()
    old = json.loads((day1 / "sheets" / "survey_results.json").read_text())
    new = json.loads((out / "sheets" / "survey_results.json").read_text())
    assert {k: v for k, v in new.items() if k != "header"} == {
        k: v for k, v in old.items() if k != "header"}
    assert new["header"]["sheets_used"] == [f"Chart I-3 of run {_uid(day1)} (day1)"]
    for r in res["calibration"]:
        assert abs(r["error"]) < 4 * r["sigma"], r


def test_cli_refuses_prior_in_one_line(day1, tmp_path):
    cfg = tmp_path / "other.toml"
    cfg.write_text('[identity.unit]\nisu = "ISU-999"\n')
    p = subprocess.run([sys.executable, "-m", "laboratory.cli", "day", "--config", str(cfg),
                        "--out", str(tmp_path / "x"), "--only", "II-11", "--prior", str(day1),
                        "--quiet"], capture_output=True, text=True)
    assert p.returncode == 2
    assert p.stderr.strip().splitlines() == [
        f"error: --prior: unit isu of {day1} is 'ISU-000-001', the config's "
        "[identity.unit] isu is 'ISU-999'"]
    assert not (tmp_path / "x").exists() or not any((tmp_path / "x").iterdir())
