"""Required accuracy drives the day (II-6.2, issue 18): [plan], --require, the Counter
Settings Sheet's reasons, refusals, and `station plan`'s Charts II-18..II-24."""

from __future__ import annotations

import io
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from laboratory.isu.planning import CHARTS, run_plan
from laboratory.isu.spec import noise_spec, site_of
from procedures.isu.accuracy import GATES, Predictor, Times, Unreachable, choose_times
from procedures.isu.plan import DayPlan
from procedures.isu.settings import planning_lab
from station.config.isu import load_config
from station.config.plan import PlanSettings, with_required

ROOT = Path(__file__).resolve().parents[1]
DEFAULTS = PlanSettings().requirements()
TIGHT_DRIFT = 0.008  # deg/hr: below the 0.0091 the manual's 10 minutes give


def station(cfg_seed: int, rng: np.random.Generator) -> object:
    """A station with its gyro and accelerometer noise and its latitude drawn within the
    config's admissible ranges."""
    arw = float(rng.uniform(0.002, 0.005))
    acc = float(rng.uniform(5.0, 15.0))
    lat = float(rng.uniform(-60.0, 60.0))
    return load_config(seed=cfg_seed, overrides={
        "site": {"latitude_deg": lat},
        "isu": {"gyros": [{**g, "arw_deg_rt_hr": arw} for g in _default("gyros")],
                "accels": [{**a, "noise_micro_g_rt_hz": acc} for a in _default("accels")]},
    })


def _default(kind: str) -> list[dict]:
    from station.config.isu import default_dict

    return default_dict()["isu"][kind]


def cli(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "laboratory.cli", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("seed", [3, 11])
def test_tighter_requirement_lengthens_exactly_its_gate(seed):
    """On a random station, each requirement at 0.8 of its predicted sigma at the manual's
    time lengthens its own gate to the smallest whole second (turn) meeting it, and only
    that gate."""
    rng = np.random.default_rng(seed)
    cfg = station(seed, rng)
    lab = planning_lab(DayPlan(), site_of(cfg), noise_spec(cfg))
    pred = Predictor(lab)
    at_default = pred.quantities(pred.covariance(Times()))
    names = {"gyro 7-15": "gyro_drift_deg_hr", "accel vertical": "accel_scale_factor_ppm"}
    for gate, name in names.items():
        loose = {n: 10 * at_default[n] for n in DEFAULTS}
        req = {**loose, name: 0.8 * at_default[name]}
        times, choices = choose_times(req, 3600.0, lab, predictor=pred)
        for g in GATES:
            assert (times.get(g) > Times().get(g)) == (g == gate), (gate, g, times)
        c = next(c for c in choices if c.gate == gate)
        assert c.requirement == name and c.why == f"lengthened for {name} = {req[name]:g}"
        assert c.predicted <= req[name]
        shorter = pred.quantities(pred.covariance(times.set(gate, c.chosen - 1)))[name]
        assert shorter > req[name]
        assert all(c.why.startswith("default") for c in choices if c.gate != gate)


def test_default_requirements_keep_the_manuals_times():
    cfg = load_config()
    lab = planning_lab(DayPlan(), site_of(cfg), noise_spec(cfg))
    times, choices = choose_times(DEFAULTS, 3600.0, lab)
    assert times == Times()
    assert [c.why.split(":")[0] for c in choices] == ["default"] * 4


def test_unreachable_and_unknown_requirements_refused_in_one_line():
    cfg = load_config()
    lab = planning_lab(DayPlan(), site_of(cfg), noise_spec(cfg))
    with pytest.raises(Unreachable, match=r"^accel_bias_micro_g = 2: no admissible gate"):
        choose_times({**DEFAULTS, "accel_bias_micro_g": 2.0}, 3600.0, lab)
    with pytest.raises(Unreachable, match=r"^max_gate_minutes 20: shorter than"):
        choose_times(DEFAULTS, 1200.0, lab)
    with pytest.raises(ValueError, match=r"--require 'gyro_R=1': give NAME=VALUE"):
        with_required(PlanSettings(), ["gyro_R=1"])
    with pytest.raises(ValueError, match=r"--require gyro_drift_deg_hr: "):
        with_required(PlanSettings(), ["gyro_drift_deg_hr=-1"])
    assert with_required(PlanSettings(), ["gyro_drift_deg_hr=0.01"]).gyro_drift_deg_hr == 0.01


def test_unreachable_day_refused_writing_nothing(tmp_path):
    out = tmp_path / "day"
    p = cli("day", "--require", "accel_bias_micro_g=2", "--out", str(out), "--quiet")
    assert p.returncode == 2, p.stderr
    assert p.stderr.strip().count("\n") == 0 and "accel_bias_micro_g = 2" in p.stderr
    assert not out.exists()
    p = cli("day", "--require", "nonsense=2", "--out", str(out), "--quiet")
    assert p.returncode == 2 and "--require 'nonsense=2'" in p.stderr
    assert not out.exists()


@pytest.fixture(scope="module")
def tight_day(tmp_path_factory):
    out = tmp_path_factory.mktemp("tight") / "day"
    p = cli("day", "--require", f"gyro_drift_deg_hr={TIGHT_DRIFT}", "--out", str(out),
            "--quiet", "--seed", "7")
    assert p.returncode == 0, p.stderr
    return out


def test_tight_day_lengthens_the_gyro_gate_and_meets_it(tight_day):
    sheet = json.loads((tight_day / "sheets" / "counter_settings.json").read_text())
    gates = sheet["gates"]
    assert gates["gyro 7-15"]["why"] == f"lengthened for gyro_drift_deg_hr = {TIGHT_DRIFT:g}"
    chosen = gates["gyro 7-15"]["chosen"]
    assert chosen > 600 and gates["gyro 7-15"]["predicted"] <= TIGHT_DRIFT
    for g in ("gyro 1-6", "accel vertical", "accel horizontal"):
        assert gates[g]["chosen"] == gates[g]["default"] and gates[g]["why"].startswith("def")
    presets = sheet["presets"]
    assert presets["gyro 7"]["2"] == round(chosen / 1e-6)  # S1^T = 1 us
    assert presets["gyro 1"]["1"] == 10 and presets["accel 7"]["1"] == 600 * 20000
    assert "lengthened for gyro_drift_deg_hr" in sheet["basis"]["gyro 7-15"]
    rows = json.loads((tight_day / "results.json").read_text())["calibration"]
    g = load_config().site.g_local_mps2 / 9.80665
    scale = {"R": 1.0, "B_I": g, "B_O": g, "B_S": g, "C_II": g * g, "C_SS": g * g}
    seen = 0
    for r in rows:
        if r["instrument"].startswith("gyro") and r["parameter"] in scale:
            # the day's own sigma (measured geometry and timeline) meets the requirement
            assert r["sigma"] * scale[r["parameter"]] <= TIGHT_DRIFT * 1.02, r
            assert abs(r["error"]) <= 4 * r["sigma"], r
            seen += 1
    assert seen == 18


def test_station_plan_charts_and_the_days_sigma(tight_day, tmp_path):
    """`station plan` writes every chart; its curve at the manual's time is the day's
    predicted sigma (scale factor at 10 turns, D0 at 30 minutes with levels)."""
    out = tmp_path / "plan"
    doc = run_plan(load_config(), out, Console(file=io.StringIO(), width=120))
    for chart in CHARTS:
        assert (out / f"chart_{chart}.png").read_bytes()[:4] == b"\x89PNG"
    table = (out / "accuracy.csv").read_text().splitlines()
    assert table[0] == "chart,quantity,gate,level_corrected,time,time_units,units,sigma"
    assert doc["times"] == {"turns": 10, "gyro_s": 600.0, "accel_vertical_s": 600.0,
                            "accel_horizontal_s": 1800.0}
    both = {line.split(",")[0] for line in table[1:] if ",False," in line}
    assert both == {"II-21", "II-22"}  # the charts drawn without level corrections

    def curve(chart: str, quantity: str, time: float) -> float:
        for line in table[1:]:
            c, q, _, level, t, _, _, s = line.split(",")
            if c == chart and q == quantity and level == "True" and float(t) == time:
                return float(s)
        raise AssertionError((chart, quantity, time))

    rows = json.loads((tight_day / "results.json").read_text())["calibration"]
    by = {(r["instrument"], r["parameter"]): r for r in rows}
    day_sf = max(by[(f"gyro{k}", "DeltaPhi")]["sigma"] / by[(f"gyro{k}", "DeltaPhi")]["estimate"]
                 for k in (1, 2, 3))
    day_d0 = 1e6 * max(by[(f"accel{k}", "D0")]["sigma"] for k in (1, 2, 3))
    assert math.isclose(curve("II-18", "gyro_scale_factor", 10), day_sf, rel_tol=0.02)
    assert math.isclose(curve("II-24", "accel_bias_micro_g", 1800), day_d0, rel_tol=0.1)
    # the longer gate halves nothing it should not: the plan's R curve falls with time
    r = [curve("II-19", "gyro R", t) for t in (300.0, 600.0, 1800.0)]
    assert r[0] > r[1] > r[2]
