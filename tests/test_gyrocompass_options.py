"""The report 001 options of issue 20: the re-analysis with the run's own configuration,
the error budget of eqs. 26-27, the pre-test set-up of section 4.1 and the variation
studies of section 1."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from laboratory.cli import app


def _config(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "cigtf.toml"
    p.write_text("[cigtf]\n" + body)
    return p


def test_analyse_takes_the_runs_own_config(tmp_path):
    """Issue 19: --analyse DIR recomputes the truth from the run's saved config.toml (a
    64 deg run), not the defaults; an explicit --config still wins."""
    cfg = _config(tmp_path, "latitude_deg = 64.0\n")
    out = tmp_path / "run"
    r = CliRunner().invoke(app, ["gyrocompass-test", "--config", str(cfg), "--out", str(out),
                                 "--seed", "4"])
    assert r.exit_code == 0, r.output
    truth = json.loads((out / "gyrocompass.json").read_text())["truth"]["theta_arcsec"]
    r = CliRunner().invoke(app, ["gyrocompass-test", "--analyse", str(out)])
    assert r.exit_code == 0, r.output
    again = json.loads((out / "gyrocompass_analysis.json").read_text())
    assert again["truth"]["theta_arcsec"] == truth
    from laboratory.cigtf.gyrocompassing import run_config
    assert run_config(out, None) == out / "config.toml"
    assert run_config(out, cfg) == cfg


def _true_values(seed: int, cfg: Path) -> tuple[dict, float, float, float]:
    """The simulator's budget terms, b, c (arcsec) and the 180 deg null's error (arcsec)."""
    from sim.cigtf.world import CigtfWorld
    from sim.units import to_arcsec
    from station.config.cigtf import load_cigtf_params

    w = CigtfWorld(seed, load_cigtf_params(cfg))
    m = w.misalignments
    return (w.truth_budget(), to_arcsec(m.b), to_arcsec(m.c),
            to_arcsec(w.fixture._detent("v", 180)))


def test_budget_terms_explain_the_uncorrected_theta_and_eq27_removes_them(tmp_path):
    """Eqs. 26-27 on a poorly levelled fixture at 60 deg (b tan(lat) tens of arcsec): the
    budget's terms from the simulator's true values equal theta (eq. 28) - (-(a + d))
    within the phase sigma; eq. 27 with the levels' b, c (read to 0.5 arcsec), the gyro's
    D_I, D_OS and the null's error takes them out, leaving -(a + d) within its sigma."""
    from laboratory.cigtf.gyrocompassing import run_gyrocompass_test
    from procedures.cigtf.budget import budget_terms
    from station.config.cigtf import load_cigtf_eq27, load_cigtf_params

    seed = 3
    base = _config(tmp_path, "latitude_deg = 60.0\nlevel_sd_arcsec = 20.0\npretest_setup = false\n")
    terms, b, c, eps = _true_values(seed, base)
    assert abs(terms["b omega sin"]) > 10.0  # the test discriminates
    # the closed forms of procedures/cigtf/budget.py agree with the simulator's
    mine = budget_terms(b, c, 0.4, 0.25, eps, -eps, 60.0)
    for k, v in mine.items():
        assert v == pytest.approx(terms[k], rel=1e-4, abs=1e-6)
    cfg = _config(tmp_path, "latitude_deg = 60.0\nlevel_sd_arcsec = 20.0\npretest_setup = false\n"
                  "[cigtf.eq27]\napply = true\n"
                  f"b_arcsec = {b + 0.3}\nc_arcsec = {c - 0.3}\nlevel_sigma_arcsec = 0.5\n"
                  "d_i_deg_hr = 0.4\nd_os_deg_hr = 0.25\ndrift_sigma_deg_hr = 0.01\n"
                  f"v180_error_arcsec = {eps}\nnull_sigma_arcsec = 0.05\n")
    res = run_gyrocompass_test(seed, tmp_path / "run", params=load_cigtf_params(cfg),
                               eq27=load_cigtf_eq27(cfg))
    north = res["truth"]["north_arcsec"]
    total = next(r for r in res["budget"] if r["term"] == "total")
    assert total["truth"] == pytest.approx(res["truth"]["theta_arcsec"] - north, abs=1e-9)
    for p in res["phases"]:
        assert abs(p["theta_arcsec"] - north - total["truth"]) < 4 * p["sigma_arcsec"], p
        assert abs(p["theta_arcsec"] - north) > 4 * p["sigma_arcsec"]  # the bias is there
    assert res["eq27"]["applied"]
    for p in res["eq27"]["phases"]:
        assert abs(p["theta_arcsec"] - north) < 4 * p["sigma_arcsec"], p
        assert p["truth_check"] == "within 4 sigma"
    # the record keeps the table; --analyse gives it back from the journal and config.toml
    saved = json.loads((tmp_path / "run" / "gyrocompass.json").read_text())
    assert [r["term"] for r in saved["budget"]] == [
        "b D_I", "c D_OS", "b omega sin", "(3 epsilon + eta)/4", "total"]
    assert (tmp_path / "run" / "sheets" / "gyrocompass_budget.json").is_file()
    html = (tmp_path / "run" / "report.html").read_text()
    assert "eqs. 26-27" in html and "b omega sin" in html


def test_eq27_from_the_command_line_and_analyse(tmp_path):
    """`--eq27` applies the [cigtf.eq27] values; --analyse DIR applies them again from the
    run's start note."""
    cfg = _config(tmp_path, "[cigtf.eq27]\nb_arcsec = 1.0\n")
    out = tmp_path / "run"
    r = CliRunner().invoke(app, ["gyrocompass-test", "--config", str(cfg), "--out", str(out),
                                 "--eq27"])
    assert r.exit_code == 0, r.output
    assert "theta (eq. 27)" in r.output and "Error budget" in r.output
    res = json.loads((out / "gyrocompass.json").read_text())
    assert res["eq27"]["values"]["b_arcsec"] == 1.0
    r = CliRunner().invoke(app, ["gyrocompass-test", "--analyse", str(out)])
    assert r.exit_code == 0, r.output
    again = json.loads((out / "gyrocompass_analysis.json").read_text())
    assert again["eq27"]["phases"] == res["eq27"]["phases"]
    assert again["budget"] == res["budget"]
