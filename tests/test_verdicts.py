"""Limits and verdicts (issue 15): every result row judged against its [limits] entry, the
run's outcome, exit 3 with one line for a failed verdict, the default limits passing the
CIGTF as configured and judging the ESG by the report's readout goal (seeds drawn at random,
named in any failure), "NO LIMIT" where
no limit is set, and bad [limits] entries refused naming the field."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
from pathlib import Path

import pytest

from laboratory.cigtf.gyrocompassing import run_gyrocompass_test
from laboratory.esg.calibration import run_esg_calibration
from laboratory.verdicts import judge_constant, judge_constants, run_verdict, truth_check
from station.config.cigtf import load_cigtf_limits
from station.config.esg import load_esg_limits
from station.config.file import ConfigError
from station.config.isu import load_config
from station.config.limits import ConstantLimit, IsuLimits
from station.errors import VerdictFailed

REPO = Path(__file__).resolve().parents[1]
# a short day that determines constants (II-11 at position 7 alone determines none)
SHORT = ("--only", "II-6")
# the brief's rule: nothing tuned to one seed. A new draw each run; under pytest-xdist the
# run's id seeds it, so that every worker collects the same tests
SEEDS = random.Random(os.environ.get("PYTEST_XDIST_TESTRUNUID"))


def _station(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "laboratory.cli", *args],
                          capture_output=True, text=True, cwd=REPO, timeout=900)


def _row(estimate: float | None, sigma: float | None = 0.01, error: float | None = None,
         units: str = "deg/hr") -> dict:
    return {"instrument": "gyro1", "parameter": "R", "units": units, "estimate": estimate,
            "sigma": sigma, "error": error}


def test_row_judged_by_its_band_and_its_required_accuracy() -> None:
    lim = ConstantLimit(max_abs=2.0, max_sigma=0.02)
    assert judge_constant(_row(1.5), lim)["verdict"] == "PASS"
    assert judge_constant(_row(-2.5), lim)["verdict"] == "FAIL"
    assert judge_constant(_row(1.5, sigma=0.03), lim)["verdict"] == "FAIL"
    r = judge_constant(_row(1.5), lim)
    assert (r["limit"], r["limit_text"]) == (2.0, "|x| <= 2 deg/hr; sigma <= 0.02 deg/hr")
    band = ConstantLimit(nominal=3.0, max_abs=0.03)
    assert judge_constant(_row(3.02, units="arcsec/pulse"), band)["limit_text"] == \
        "|x - 3| <= 0.03 arcsec/pulse"
    assert judge_constant(_row(2.96), band)["verdict"] == "FAIL"
    iv = ConstantLimit(interval=[0.0, 3e-6])
    assert judge_constant(_row(1e-6), iv)["verdict"] == "PASS"
    assert judge_constant(_row(-1e-9), iv)["verdict"] == "FAIL"


def test_missing_limit_and_undetermined_constant_give_no_limit() -> None:
    r = judge_constant(_row(1.0), None)
    assert (r["limit"], r["limit_text"], r["verdict"]) == (None, "no limit", "NO LIMIT")
    r = judge_constant(_row(None, sigma=None), ConstantLimit(max_abs=1.0))
    assert r["verdict"] == "NO LIMIT" and r["limit_text"].startswith("not determined")
    rows = judge_constants([_row(1.0)], IsuLimits())
    assert run_verdict(rows) == {"outcome": "NO LIMITS", "failed": []}


def test_truth_check_is_separate_from_the_verdict() -> None:
    """An estimate 5 sigma from the truth but inside its limit: PASS, beyond 4 sigma."""
    r = judge_constant(_row(1.0, sigma=0.01, error=0.05), ConstantLimit(max_abs=2.0))
    assert (r["verdict"], r["truth_check"]) == ("PASS", "beyond 4 sigma")
    assert truth_check([0.039], [0.01]) == "within 4 sigma"
    assert truth_check([None], [0.01]) is None  # no truth: a real or served laboratory


def test_kind_entry_and_instrument_entry_merge() -> None:
    lim = IsuLimits.model_validate({"constants": {
        "gyro.R": {"max_abs": 5.0, "max_sigma": 0.02}, "gyro2.R": {"max_abs": 0.5}}})
    assert lim.constant("gyro2", "R") == ConstantLimit(max_abs=0.5, max_sigma=0.02)
    assert lim.constant("gyro1", "R") == ConstantLimit(max_abs=5.0, max_sigma=0.02)
    assert lim.constant("accel1", "D0") is None


def test_verdict_failed_exit_code_and_line() -> None:
    e = VerdictFailed(["gyro1.R", "gyro2.R"])
    assert e.exit_code == 3 and str(e) == "FAIL (2 rows: gyro1.R, gyro2.R)"


def test_a_constant_that_misses_its_limit_fails_the_run_and_exits_3(tmp_path: Path) -> None:
    cfg = tmp_path / "tight.toml"
    cfg.write_text('[limits.constants]\n'  # deg/pulse (Chart II-5): 0.001 arcsec/pulse
                   '"gyro1.DeltaPhi" = { nominal = 8.3333e-4, max_abs = 2.8e-7 }\n')
    out = tmp_path / "run"
    p = _station("day", *SHORT, "--quiet", "--config", str(cfg), "--out", str(out))
    assert p.returncode == 3, p.stderr
    assert p.stderr.strip().splitlines()[-1] == "verdict: FAIL (1 rows: gyro1.DeltaPhi)"
    res = json.loads((out / "results.json").read_text())
    row = next(r for r in res["calibration"]
               if (r["instrument"], r["parameter"]) == ("gyro1", "DeltaPhi"))
    # the configured scale factor is 3.0012 arcsec/pulse: 8.33667e-4 deg/pulse
    assert abs(row["estimate"] - 8.3333e-4) > 2.8e-7
    assert (row["verdict"], row["limit"]) == ("FAIL", 2.8e-7)
    assert row["limit_text"].startswith("|x - 0.00083333| <= 2.8e-07 deg/pulse"), row["limit_text"]
    assert res["verdict"] == {"outcome": "FAIL", "failed": ["gyro1.DeltaPhi"]}
    others = [r for r in res["calibration"] if r is not row]
    assert {r["verdict"] for r in others} <= {"PASS", "NO LIMIT"}


@pytest.mark.parametrize("seed", [1970, SEEDS.randrange(1, 10**6)])
def test_default_limits_pass_the_default_day(tmp_path: Path, seed: int) -> None:
    out = tmp_path / "day"
    p = _station("day", "--quiet", "--seed", str(seed), "--out", str(out))
    assert p.returncode == 0, f"seed {seed}: {p.stderr}"
    res = json.loads((out / "results.json").read_text())
    assert res["verdict"] == {"outcome": "PASS", "failed": []}, seed
    judged = res["calibration"] + [a for a in res["alignment"] if "skipped" not in a]
    assert all(r["verdict"] in ("PASS", "NO LIMIT") for r in judged)
    assert all(r["truth_check"] in ("within 4 sigma", "beyond 4 sigma") for r in judged)
    assert {a["verdict"] for a in res["alignment"]} == {"PASS"}


def test_default_limits_pass_cigtf_and_judge_esg_by_the_goal_at_random_seeds(
        tmp_path: Path) -> None:
    """The CIGTF passes its default limits at any seed. The ESG's default limit is the
    report's 15 arcsec readout goal, which some random laboratories miss (2026-11-24: 5 of
    80 seeds, and seed 242942, true readout rms 17.3 and 18.5 arcsec): its verdict follows
    the measured rms, and a FAIL is never a false alarm on a laboratory well inside the
    goal (true readout rms above 10 arcsec; over 160 schedules the measured rms exceeded
    the true by at most 2.3 arcsec)."""
    seed = SEEDS.randrange(1, 10**6)
    res = run_gyrocompass_test(seed, tmp_path / "cigtf", limits=load_cigtf_limits(None))
    assert res["verdict"] == {"outcome": "PASS", "failed": []}, seed
    for p in res["phases"]:
        assert p["verdict"] == "PASS" and p["limit"] == 20.0
        assert p["instability_arcsec"] <= 20.0
    seed = SEEDS.randrange(1, 10**6)
    res = run_esg_calibration(seed, tmp_path / "esg", with_study=False,
                              limits=load_esg_limits(None))
    for s in res["schedules"]:
        assert s["limit_text"] == "readout rms <= 15 arcsec"
        assert s["verdict"] == ("PASS" if s["readout_rms_arcsec"] <= 15.0 else "FAIL"), seed
        if s["verdict"] == "FAIL":
            assert s["true_readout_rms_arcsec"] > 10.0, (seed, s)
    failed = [s for s in res["schedules"] if s["verdict"] == "FAIL"]
    assert res["verdict"]["outcome"] == ("FAIL" if failed else "PASS"), seed


def test_a_tight_cigtf_limit_fails_and_exits_3(tmp_path: Path) -> None:
    cfg = tmp_path / "cigtf.toml"
    cfg.write_text("[cigtf.limits]\nmax_operating_instability_arcsec = 0.5\n"
                   "max_shutdown_instability_arcsec = 100.0\n")
    p = _station("gyrocompass-test", "--config", str(cfg), "--out", str(tmp_path / "run"))
    assert p.returncode == 3, p.stderr
    assert p.stderr.strip().splitlines()[-1] == "verdict: FAIL (1 rows: operating phase)"


@pytest.mark.parametrize(("text", "field"), [
    ('[limits.constants]\n"gyro4.R" = { max_abs = 1.0 }\n', "limits.constants"),
    ('[limits.constants]\n"gyro.X" = { max_abs = 1.0 }\n', "limits.constants"),
    ('[limits.constants]\n"gyro.R" = { max_abs = -1.0 }\n', "limits.constants.'gyro.R'.max_abs"),
    ('[limits.constants]\n"gyro.R" = { maxabs = 1.0 }\n', "limits.constants.'gyro.R'.maxabs"),
    ('[limits.constants]\n"gyro.J" = { interval = [1.0, 0.0] }\n',
     "limits.constants.'gyro.J'.interval"),
    ('[limits.alignment]\nmirror = { max_sigma_arcsec = [1.0, 2.0] }\n',
     "limits.alignment.mirror.max_sigma_arcsec"),
    ('[limits.alignment]\nstar = { max_sigma_arcsec = [1.0, 2.0, 3.0] }\n',
     "limits.alignment"),
])
def test_bad_isu_limits_refused_naming_the_field(tmp_path: Path, text: str, field: str) -> None:
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(ConfigError) as e:
        load_config(f)
    msg = str(e.value)
    assert "\n" not in msg and f" {field}:" in msg, msg


@pytest.mark.parametrize(("loader", "text", "field"), [
    (load_cigtf_limits, "[cigtf.limits]\nmax_operating_instability_arcsec = 0\n",
     "cigtf.limits.max_operating_instability_arcsec"),
    (load_cigtf_limits, "[cigtf.limits]\ndelta = 3.0\n", "cigtf.limits.delta"),
    (load_esg_limits, "[esg.limits]\nreadout_rms_arcsec = 'x'\n",
     "esg.limits.readout_rms_arcsec"),
])
def test_bad_cigtf_and_esg_limits_refused_naming_the_field(tmp_path: Path, loader: object,
                                                           text: str, field: str) -> None:
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(ConfigError) as e:
        loader(f)  # type: ignore[operator]
    assert "\n" not in str(e.value) and field in str(e.value), str(e.value)
