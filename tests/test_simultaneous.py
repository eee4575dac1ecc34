"""II-5's remark (issue 20): with nine counters the gyro and accelerometer readings of
positions 7-14 are taken in one setting of the table. The accelerometer constants stay
within 4 predicted sigma of the simulator's truth; every gyro gate lies inside its
position's accelerometer gates; position 15 stays on Chart II-12; too few counters are
refused naming the field."""

from __future__ import annotations

import json

import pytest
from rich.console import Console

from laboratory.isu.day import DayRequest, run_day
from procedures.isu.plan import DayPlan
from station.config.file import ConfigError
from station.config.isu import load_config

QUIET = Console(quiet=True)
CHARTS = ("II-11", "II-12", "II-13", "II-14")


@pytest.fixture(scope="module")
def day(tmp_path_factory):
    cfg = load_config(seed=5, overrides={"calibration": {"simultaneous": True, "counters": 9}})
    d = tmp_path_factory.mktemp("together")
    plan = DayPlan(study_gyro_gate_s=60.0, study_accel_vertical_s=60.0,
                   study_accel_horizontal_s=60.0)
    res = run_day(DayRequest(cfg, d, only=CHARTS, quiet=True, align=False, plan=plan), QUIET)
    steps = [json.loads(x) for x in (d / "journal.jsonl").read_text().splitlines()]
    return d, res, steps


def test_accelerometer_constants_within_4_sigma(day):
    _, res, _ = day
    rows = [r for r in res["calibration"] if r["instrument"].startswith("accel")]
    assert len(rows) == 21
    for r in rows:
        assert r["estimate"] is not None and r["sigma"] > 0, r
        assert abs(r["error"]) < 4 * r["sigma"], r


def test_gyro_gates_run_inside_the_accelerometer_gates(day):
    d, _, steps = day
    records = {s["step"]: s["reading"] for s in steps
               if s.get("chart") in ("II-11+II-13", "II-12+II-14")
               and str(s.get("step", "")).startswith("9/")}
    assert sorted(records) == [f"9/m{m}" for m in sorted(range(7, 15), key=str)]
    for rec in records.values():
        g, a = rec["gyro"], rec["accel"]
        assert a["t0"] <= g["t0"] and g["t1"] <= a["t1"]
    charts = {s.get("chart") for s in steps}
    assert "II-11" not in charts and "II-13" not in charts and "II-14" not in charts
    alone = [s for s in steps if s.get("chart") == "II-12" and str(s["step"]).startswith("9/")]
    assert [s["step"] for s in alone] == ["9/m15"]
    outputs = json.loads((d / "sheets" / "counter_outputs.json").read_text())["outputs"]
    assert set(outputs["gyro 7"]) == {"7", "8", "9"} and len(outputs["accel 7"]) == 6


def test_too_few_counters_refused_naming_the_field():
    with pytest.raises(ConfigError, match="counters >= 9"):
        load_config(seed=1, overrides={"calibration": {"simultaneous": True}})
    with pytest.raises(ConfigError, match="counters"):
        load_config(seed=1, overrides={"calibration": {"counters": 13}})
