"""II-6.1's resolver-setting precision options (issue 20): phi3, phi4 set to a coarser
precision (about 1 deg for the scale factor positions 1-6), the rounding's uniform error in
the predicted sigma; the simulator's truth within 4 of it."""

from __future__ import annotations

import json

import pytest
from rich.console import Console

from laboratory.isu.day import DayRequest, run_day
from station.config.calibration import CalibrationOptions, set_to
from station.config.isu import load_config

QUIET = Console(quiet=True)
CHARTS = ("II-6", "II-11", "II-12", "II-13", "II-14")


@pytest.fixture(scope="module")
def days(tmp_path_factory):
    out = {}
    for name, opts in (("fine", {}), ("coarse", {"precision_scale_factor_arcsec": 3600.0,
                                                 "precision_accel_arcsec": 10.0})):
        cfg = load_config(seed=1, overrides={"calibration": opts})
        d = tmp_path_factory.mktemp(name)
        res = run_day(DayRequest(cfg, d, only=CHARTS, quiet=True, align=False), QUIET)
        out[name] = (d, {(r["instrument"], r["parameter"]): r for r in res["calibration"]})
    return out


def test_coarse_settings_within_4_predicted_sigma(days):
    _, rows = days["coarse"]
    estimated = [r for r in rows.values() if r["estimate"] is not None]
    assert len(estimated) >= 3 * 4 + 3 * 7
    for r in estimated:
        assert r["sigma"] > 0 and abs(r["error"]) < 4 * r["sigma"], r


def test_the_precision_enters_the_predicted_sigma(days):
    """A degree on positions 1-6 leaves the scale factors (second order) and costs the
    (Q^G)^-1 elements; 10 arcsec on 7-14 costs the accelerometers' cross-axis terms."""
    fine, coarse = days["fine"][1], days["coarse"][1]
    for k in (1, 2, 3):
        j = k % 3 + 1
        assert coarse[(f"gyro{k}", f"G.B{j}")]["sigma"] > 100 * fine[(f"gyro{k}", f"G.B{j}")][
            "sigma"]
        assert coarse[(f"accel{k}", f"A.B{j}")]["sigma"] > fine[(f"accel{k}", f"A.B{j}")][
            "sigma"]


def test_settings_are_commanded_to_the_precision(days):
    d, _ = days["coarse"]
    steps = [json.loads(x) for x in (d / "journal.jsonl").read_text().splitlines()]
    sets = [s for s in steps if s.get("chart") == "II-6" and str(s.get("step")).startswith("7/")]
    assert len(sets) == 3
    for s in sets:  # the sheet's settings, and the whole degrees the table was set to
        r = s["reading"]
        assert r["set_deg"] == [round(r["phi3"]), round(r["phi4"])]
        assert r["phi3"] != round(r["phi3"])

def test_set_to_rounds_to_the_precision():
    assert set_to(12.3456, 0.0) == 12.3456
    assert set_to(12.6, 3600.0) == 13.0
    assert set_to(12.3456, 36.0) == pytest.approx(12.35)
    assert CalibrationOptions(precision_gyro_arcsec=60.0).precisions() == {"G": 60.0}
