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
