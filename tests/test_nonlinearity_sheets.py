"""Charts II-8 and II-9: the nonlinearity experiments' Counter Settings and Counter Outputs
Sheets (issue 20), on a random admissible laboratory.

II-8 holds what Chart II-7 steps 6-7 set (counters 1 and k + 1, whole-turn preset, speed)
before the runs; II-9 the outputs of step 10 and the rates of steps 14-15. The Q_II fitted
from II-9 alone is the Calibration Results Sheet's, and within 4 sigma of the truth."""

from __future__ import annotations

import json
import random

import numpy as np
import pytest
from rich.console import Console

from laboratory.isu.day import DayRequest, run_day
from procedures.isu.nonlinearity import fit_nonlinearity, speed_key
from procedures.isu.plan import DayPlan
from station.config.isu import default_dict, load_config

QUIET = Console(quiet=True)


@pytest.fixture(scope="module")
def day(tmp_path_factory):
    rng = random.Random(2026_11_23)
    lat = rng.uniform(5.0, 70.0) * rng.choice([-1.0, 1.0])
    seed = rng.randrange(1, 10_000)
    gyros = default_dict()["isu"]["gyros"]
    arw = rng.uniform(0.3, 3.0)  # the angle random walk at 0.3-3x the class's
    cfg = load_config(seed=seed, overrides={
        "site": {"latitude_deg": lat},
        "isu": {"gyros": [{**g, "arw_deg_rt_hr": g["arw_deg_rt_hr"] * arw} for g in gyros]}})
    d = tmp_path_factory.mktemp("nl")
    res = run_day(DayRequest(cfg, d, only=("II-7",), quiet=True, align=False), QUIET)
    sheets = {n: json.loads((d / "sheets" / f"{n}.json").read_text())
              for n in ("nonlinearity_counter_settings", "nonlinearity_counter_outputs",
                        "check_II-7")}
    return res, sheets


def test_chart_II8_holds_the_settings_of_every_gyro_and_speed(day):
    _, sheets = day
    plan = DayPlan()
    preset = plan.nonlinearity_turns * plan.rotation_pulses_per_rev
    got = sheets["nonlinearity_counter_settings"]["gyros"]
    assert sorted(got) == ["1", "2", "3"]
    for k in (1, 2, 3):
        assert sorted(got[str(k)]) == sorted(speed_key(r) for r in plan.nonlinearity_rates_deg_s)
        for key, gate in got[str(k)].items():
            assert gate["counters"] == [1, k + 1]
            assert gate["preset"] == preset
            assert speed_key(gate["rate_deg_s"]) == key
    assert sheets["nonlinearity_counter_settings"]["header"]["sheets_used"] == ["Chart II-1"]


def test_chart_II9_holds_step_10_outputs_and_fits_the_sheets_Q_II(day):
    res, sheets = day
    out = sheets["nonlinearity_counter_outputs"]["gyros"]
    steps = {s["number"]: s["reading"] for s in sheets["check_II-7"]["steps"]}
    rows = {(r["instrument"], r["parameter"]): r for r in res["calibration"]}
    for k in (1, 2, 3):
        series = []
        for key, o in out[str(k)].items():
            reading = steps[f"10/g{k}/{key}"]
            assert (o["ticks"], o["counts"]) == (reading["ticks"], reading["counts"])
            assert o["w_deg_hr"] == reading["w_deg_hr"] and o["p_dot"] == reading["p_dot"]
            series.append({**o, "rate_deg_s": float(key)})
        series.sort(key=lambda r: r["rate_deg_s"])
        row = rows[(f"gyro{k}", "Q_II")]
        assert row["estimate"] is not None and row["sigma"] > 0
        assert abs(row["error"]) < 4 * row["sigma"], row
        # the sheet alone (equal weights) gives a Q_II within 4 sigma of the truth too
        w = np.array([r["w_deg_hr"] for r in series])
        assert np.all(np.sign(w) == np.sign([r["rate_deg_s"] for r in series]))
        fit = fit_nonlinearity(series, 1.0)
        truth = row["estimate"] - row["error"]
        assert abs(fit["Q_II"] - truth) < 4 * row["sigma"], (k, fit["Q_II"], truth)
