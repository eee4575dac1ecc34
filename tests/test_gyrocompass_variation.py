"""The variation studies of report 001 section 1 (laboratory/cigtf/variation.py): the test
per setting of the rotor voltage or of the input axis's azimuth, theta fitted against the
variable; the sensitivity found against the simulator's model."""

from __future__ import annotations

import json
import math

import pytest
from typer.testing import CliRunner

from laboratory.cigtf.variation import parse_vary, run_variation, weighted_fit
from laboratory.cli import app
from sim.cigtf.sdf_gyro import EARTH_FIELD_GAUSS
from sim.cigtf.world import NOMINAL_ROTOR_V, CigtfParams, CigtfWorld
from sim.units import EARTH_RATE, deg_per_hr, to_arcsec


def test_parse_vary_names_the_fault():
    assert parse_vary("rotor-voltage=22,26,30") == ("rotor-voltage", [22.0, 26.0, 30.0])
    assert parse_vary("azimuth=-2,0,2") == ("azimuth", [-2.0, 0.0, 2.0])
    for bad, why in (("voltage=1,2", "expected rotor-voltage"), ("azimuth=1", "two distinct"),
                     ("azimuth=0.5,1", "whole degrees"), ("rotor-voltage=5,26", "10..40"),
                     ("rotor-voltage=a,b", "numbers"), ("azimuth=1,1", "two distinct")):
        with pytest.raises(ValueError, match=why):
            parse_vary(bad)


def test_weighted_fit_recovers_a_line_and_its_sigma():
    slope, sigma, icpt = weighted_fit([0.0, 1.0, 2.0], [1.0, 3.0, 5.0], [1.0, 1.0, 1.0])
    assert (slope, icpt) == pytest.approx((2.0, 1.0))
    assert sigma == pytest.approx(1.0 / math.sqrt(2.0))  # 1 / sqrt(sum (x - mean)^2)


def test_magnetic_term_is_what_the_four_orientation_sum_leaves():
    """theta's magnetic part: D_M B_west / (omega_E cos lat) (orientations 1 and 3 have I
    west), scaled by the rotor voltage; to the GSF's share of the field's north component and
    the fixture's few arcsec of azimuth (a levelled fixture: no set-up, 3 arcsec)."""
    from dataclasses import replace

    p = replace(CigtfParams(), magnetic_drift_deg_hr_per_gauss=0.02, rotor_voltage_v=32.0,
                pretest_setup=False)
    w = CigtfWorld(3, p)
    wc = EARTH_RATE * math.cos(w.latitude)
    d_m = deg_per_hr(0.02) * 32.0 / NOMINAL_ROTOR_V
    assert w.magnetic_theta_arcsec() == pytest.approx(
        to_arcsec(d_m * EARTH_FIELD_GAUSS[2] / wc), rel=1e-3)
    assert CigtfWorld(3).magnetic_theta_arcsec() == 0.0  # the Appendix I gyro: none


def test_rotor_voltage_study_finds_the_magnetic_sensitivity(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text("[cigtf]\nmagnetic_drift_deg_hr_per_gauss = 0.02\n")
    out = tmp_path / "v"
    r = CliRunner().invoke(app, ["gyrocompass-test", "--vary", "rotor-voltage=20,26,32",
                                 "--seed", "3", "--config", str(cfg), "--out", str(out)])
    assert r.exit_code == 0, r.output
    res = json.loads((out / "variation.json").read_text())
    assert [s["run_dir"] for s in res["settings"]] == [
        "rotor-voltage-20", "rotor-voltage-26", "rotor-voltage-32"]
    assert all((out / s["run_dir"] / "gyrocompass.json").is_file() for s in res["settings"])
    # the model: -0.68 arcsec/V (the magnetic term over 26 V) and the set-ups' residuals
    assert res["truth"]["sensitivity"] == pytest.approx(-17.65 / 26.0, abs=0.05)
    assert abs(res["sensitivity"] - res["truth"]["sensitivity"]) <= 4.0 * res["sigma"]
    assert res["sigma"] < 0.2  # three 35-run tests resolve it
    assert "sensitivity d theta / d rotor-voltage" in r.output


def test_rotor_voltage_leaves_the_appendix_i_gyro_alone(tmp_path):
    res = run_variation(5, tmp_path, "rotor-voltage", [20.0, 32.0])
    assert abs(res["truth"]["sensitivity"]) < 0.05  # only the set-ups' residuals differ
    assert abs(res["sensitivity"] - res["truth"]["sensitivity"]) <= 4.0 * res["sigma"]


def test_azimuth_study_follows_the_input_axis(tmp_path):
    """Orientation 1 at vertical psi: theta = -3600 psi arcsec/deg to the GSF's linearity;
    each setting's sigma carries its GSF's error (theta is thousands of arcsec)."""
    res = run_variation(3, tmp_path, "azimuth", [-2.0, -1.0, 0.0, 1.0, 2.0])
    assert res["truth"]["sensitivity"] == pytest.approx(-3600.0, abs=5.0)
    assert abs(res["sensitivity"] - res["truth"]["sensitivity"]) <= 4.0 * res["sigma"]
    assert res["sigma"] < 15.0
    big = [s for s in res["settings"] if abs(s["value"]) == 2.0]
    assert all(s["sigma_arcsec"] > 5 * s["standard_error_arcsec"] for s in big)
    assert res["error_sensitivity"] == pytest.approx(res["sensitivity"] + 3600.0)


def _words(text: str) -> str:
    """The output's words (typer may box a refusal and wrap it)."""
    return " ".join(w for w in text.replace("│", " ").split())


def test_vary_refuses_resume_links_and_bad_values(tmp_path):
    for extra in (["--resume", str(tmp_path)], ["--links", str(tmp_path)]):
        r = CliRunner().invoke(app, ["gyrocompass-test", "--vary", "azimuth=0,1", *extra])
        assert r.exit_code == 2 and "not with --resume or --links" in _words(r.output)
    r = CliRunner().invoke(app, ["gyrocompass-test", "--vary", "azimuth=0.5,1", "--out",
                                 str(tmp_path / "x")])
    assert r.exit_code == 2 and "whole degrees" in _words(r.output)
    assert not (tmp_path / "x").exists()


def test_a_failed_write_of_variation_json_leaves_the_earlier_file_whole(tmp_path, monkeypatch):
    """variation.json is replaced whole or not at all: a write that fails half way (the
    disk full after the first bytes) leaves the earlier study's file as it was, and no
    temporary beside it. Before, write_text truncated it first."""
    import os

    from laboratory.cigtf import variation

    first = {"variable": "azimuth", "sensitivity": 1.5, "settings": [{"value": 0.0}]}
    variation.write_variation(tmp_path, first)
    before = (tmp_path / "variation.json").read_bytes()
    assert json.loads(before) == first and before.endswith(b"}\n")
    real_write = os.write

    def disk_full(fd: int, data: bytes) -> int:
        real_write(fd, bytes(data)[:5])
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("station.files.os.write", disk_full)
    with pytest.raises(OSError):
        variation.write_variation(tmp_path, {**first, "sensitivity": 2.5, "pad": "x" * 1000})
    monkeypatch.setattr("station.files.os.write", real_write)
    assert (tmp_path / "variation.json").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["variation.json"]
