"""`station plan --verify` (issue 18): a study's gate fixed for a sweep, and the verify table
of a small campaign (6 seeds, 2 times, in process) against the campaign's own errors and
the Predictor."""

from __future__ import annotations

import csv
import io
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from laboratory.campaign.spec import PLAN_PREFIX
from laboratory.campaign.store import CampaignStore
from laboratory.campaign.summary import interval
from laboratory.isu.spec import noise_spec, site_of
from laboratory.isu.verify import STUDIES, parse_times, predictor, run_verify
from procedures.isu.accuracy import Times, Unreachable, choose_times
from procedures.isu.plan import DayPlan
from procedures.isu.settings import collection_times, planning_lab
from station.config.isu import load_config
from station.config.plan import PlanSettings

ROOT = Path(__file__).resolve().parents[1]
N, TIMES = 6, (120.0, 300.0)


def test_study_gate_fixed_whatever_the_requirement_and_refused_past_the_longest():
    cfg = load_config(seed=1)
    plan = DayPlan(study_gyro_gate_s=90.0, study_accel_horizontal_s=240.0)
    times, gates = collection_times(plan, site_of(cfg), noise_spec(cfg))
    assert (times.turns, times.gyro_s, times.accel_vertical_s, times.accel_horizontal_s) == \
        (10, 90.0, 600.0, 240.0)
    assert gates["gyro 7-15"].chosen == 90.0 and "for a study" in gates["gyro 7-15"].why
    # 90 s misses the 0.02 deg/hr requirement: recorded, not applied
    assert gates["gyro 7-15"].predicted > plan.requirements.gyro_drift_deg_hr
    assert gates["accel vertical"].why.startswith("default")
    with pytest.raises(ValueError, match="study_gyro_gate_s = 3700 s: longer than "
                       "max_gate_minutes 60"):
        DayPlan(study_gyro_gate_s=3700.0)
    with pytest.raises(ValueError, match="study_accel_vertical_s"):
        DayPlan(study_accel_vertical_s=0.0)
    lab = planning_lab(DayPlan(), site_of(cfg), noise_spec(cfg))
    with pytest.raises(Unreachable, match="gyro 7-15 fixed at 4000 s: outside"):
        choose_times(PlanSettings().requirements(), 3600.0, lab, fixed={"gyro 7-15": 4000.0})


def test_times_option_parsed_and_refused_naming_the_item():
    assert parse_times(["II-19=60,600"]) == {"II-19": (60.0, 600.0)}
    for bad, what in (("II-20=60", "CHART=T1"), ("II-19=a", "not a list"),
                      ("II-19=-5", "positive"), ("II-18=1.5", "whole")):
        with pytest.raises(ValueError, match=what):
            parse_times([bad])


@pytest.fixture(scope="module")
def verified(tmp_path_factory):
    out = tmp_path_factory.mktemp("verify")
    cfg = load_config(seed=5)
    table = run_verify(cfg, out, Console(file=io.StringIO(), width=200), seeds=N, seed=5,
                       times={"II-24": TIMES}, charts=("II-24",), workers=0)
    return cfg, out, table


def test_verify_table_rows_observed_and_predicted(verified):
    cfg, out, table = verified
    study = STUDIES["II-24"]
    assert [(r["time"], r["instrument"]) for r in table] == \
        [(t, f"accel{k}") for t in TIMES for k in (1, 2, 3)]
    rows = CampaignStore(out / "campaign-II-24").table("rows")
    pred = predictor(cfg)
    lo, hi = interval(N)
    for r in table:
        sel = rows[(rows[PLAN_PREFIX + study.path] == r["time"])
                   & (rows["instrument"] == r["instrument"]) & (rows["parameter"] == "D0")]
        assert len(sel) == N == r["n"]
        assert r["observed"] == pytest.approx(math.sqrt(np.mean(sel["error"] ** 2)),
                                              rel=1e-12)
        want = pred.sigma(pred.covariance(Times(accel_horizontal_s=r["time"])),
                          r["instrument"], "D0")
        assert r["predicted"] == pytest.approx(want, rel=1e-12)
        assert r["ratio"] == pytest.approx(r["observed"] / r["predicted"], rel=1e-12)
        assert (r["low"], r["high"]) == pytest.approx((lo, hi))
        assert r["inside"] == (lo <= r["ratio"] <= hi)
    # longer gate, smaller predicted sigma (the chart's slope)
    assert all(a["predicted"] > b["predicted"] for a, b in zip(table[:3], table[3:],
                                                                 strict=True))
    with open(out / "verify.csv", newline="") as f:
        written = list(csv.DictReader(f))
    assert len(written) == len(table)
    assert float(written[0]["predicted"]) == pytest.approx(table[0]["predicted"], rel=1e-12)
    assert (out / "verify_II-24.png").stat().st_size > 0


def test_verify_options_refused_in_one_line(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for args, what in ((["--verify", "--seeds", "1"], "--seeds must be 2 or more"),
                       (["--times", "II-19=60"], "go with --verify"),
                       (["--verify", "--times", "II-99=1"], "--times 'II-99=1'")):
        p = subprocess.run([sys.executable, "-m", "laboratory.cli", "plan", *args, "--out",
                            str(tmp_path / "p")], cwd=ROOT, env=env, capture_output=True,
                           text=True, timeout=600)
        assert p.returncode == 2, p.stderr
        assert what in p.stderr and p.stderr.strip().count("\n") == 0, p.stderr
        assert not (tmp_path / "p").exists()


def test_the_check_before_the_run_and_ii6_share_one_answer_on_near_mountings(monkeypatch):
    """collection_times: the station's mounting (the check before the run) and the survey's
    (II-6), within SHARED_MOUNTING of each other, give one prediction, made once; a mounting
    farther off, or another plan, is predicted again (and the answer is its own)."""
    from procedures.isu import settings

    cfg = load_config(seed=3)
    site, noise = site_of(cfg), noise_spec(cfg)
    made = []
    real = settings.choose_times

    def counted(*a, **k):
        made.append(a[2].t_bi)
        return real(*a, **k)

    monkeypatch.setattr(settings, "choose_times", counted)
    monkeypatch.setattr(settings, "_CHOSEN", [])
    rng = np.random.default_rng(5)
    station = rng.normal(scale=4e-3, size=(3, 3)) + np.eye(3)  # a bolting error of ~1/4 deg
    near = station + rng.uniform(-3e-4, 3e-4, size=(3, 3))  # the survey's measurement error
    far = station + np.array([[0, 3e-3, 0], [-3e-3, 0, 0], [0, 0, 0]])  # 10 arcmin about B3
    first = collection_times(DayPlan(), site, noise, t_bi=station)
    assert collection_times(DayPlan(), site, noise, t_bi=near) == first
    assert len(made) == 1
    again = collection_times(DayPlan(), site, noise, t_bi=far)
    assert len(made) == 2 and made[1] != made[0]
    alone = real(DayPlan().requirements.requirements(), 3600.0,
                 planning_lab(DayPlan(), site, noise, t_bi=far), settings.manual_times(DayPlan()))
    assert again[0] == alone[0]
    assert [g.predicted for g in again[1].values()] == [c.predicted for c in alone[1]]
    plan = DayPlan(study_gyro_gate_s=90.0)  # another plan on the same mounting
    collection_times(plan, site, noise, t_bi=far)
    assert len(made) == 3
