"""II-6.1's bubble-level option: positions 7-15 with or without corrections (issue 20).

Uncorrected accelerometer positions (Charts II-13, II-14) keep the survey's level reading;
their predicted sigma counts the pier's tilt from that reading (the uncorrected cases of
Charts II-21/II-22), and the simulator's truth lies within 4 of it.
"""

from __future__ import annotations

import json

import pytest
from rich.console import Console
from typer.testing import CliRunner

from laboratory.cli import app
from laboratory.isu.day import DayRequest, run_day
from station.config.calibration import CalibrationOptions
from station.config.isu import load_config

QUIET = Console(quiet=True)
ACCEL = ("II-13", "II-14")


def _rows(res: dict) -> dict[tuple[str, str], dict]:
    return {(r["instrument"], r["parameter"]): r for r in res["calibration"]}


@pytest.fixture(scope="module")
def days(tmp_path_factory):
    """The same seed's accelerometer positions with and without bubble corrections."""
    out = {}
    for name, opts in (("corrected", None), ("uncorrected", {"bubble_accel": False})):
        cfg = load_config(seed=5, overrides=None if opts is None else {"calibration": opts})
        d = tmp_path_factory.mktemp(name)
        out[name] = (d, run_day(DayRequest(cfg, d, only=ACCEL, quiet=True, align=False),
                                QUIET))
    return out


def test_uncorrected_accelerometers_within_4_predicted_sigma(days):
    _, res = days["uncorrected"]
    rows = [r for r in res["calibration"] if r["instrument"].startswith("accel")]
    assert len(rows) == 21
    for r in rows:
        assert r["estimate"] is not None and r["sigma"] > 0, r
        assert abs(r["error"]) < 4 * r["sigma"], r


def test_uncorrected_sigma_counts_the_tilt_since_the_survey(days):
    """Without a reading before each gate the tilt of the hours since the survey enters the
    horizontal terms: the largest D0 sigma grows (an accelerometer whose pair turns it about
    its own horizontal axis sees the slow tilt cancel in the pair's sum, and loses the
    independent bubble errors, so its D0 may even shrink); the vertical D1 is unchanged in
    kind (sigma within a factor 3)."""
    c, u = _rows(days["corrected"][1]), _rows(days["uncorrected"][1])
    d0 = [(u[(f"accel{k}", "D0")]["sigma"], c[(f"accel{k}", "D0")]["sigma"]) for k in (1, 2, 3)]
    assert max(a for a, _ in d0) > 1.3 * max(b for _, b in d0)
    assert u != c
    for k in (1, 2, 3):
        a, b = u[(f"accel{k}", "D1")]["sigma"], c[(f"accel{k}", "D1")]["sigma"]
        assert b / 3 < a < 3 * b


def test_uncorrected_steps_read_no_level_and_carry_the_survey(days):
    d, _ = days["uncorrected"]
    steps = [json.loads(x) for x in (d / "journal.jsonl").read_text().splitlines()]
    sets = [s for s in steps
            if s.get("chart") == "II-13" and str(s.get("step", "")).startswith("6/")]
    assert sets and all("survey's level correction" in s["text"] for s in sets)
    assert all(s["reading"]["level_arcsec"] is None for s in sets)
    survey = json.loads((d / "sheets" / "survey_results.json").read_text())
    phi1 = -survey["position0_deg"][0]  # position 0 commanded phi1 = 0
    assert all(s["reading"]["phi1"] == pytest.approx(phi1, abs=1e-12) for s in sets)
    dc, _ = days["corrected"]
    steps_c = [json.loads(x) for x in (dc / "journal.jsonl").read_text().splitlines()]
    assert all(s["reading"]["level_arcsec"] is not None for s in steps_c
               if s.get("chart") == "II-13" and str(s.get("step", "")).startswith("6/"))


def test_options_default_absent_and_kinds():
    assert load_config(seed=1).calibration is None
    assert "calibration" not in load_config(seed=1).model_dump(exclude_none=True)
    assert CalibrationOptions().uncorrected() == ()
    assert CalibrationOptions(bubble_gyro=False, bubble_accel=False).uncorrected() == ("G", "A")


def test_no_bubble_refuses_an_unknown_kind(tmp_path):
    res = CliRunner().invoke(app, ["day", "--seed", "1", "--out", str(tmp_path / "x"),
                                   "--no-bubble", "gyros", "--quiet"])
    assert res.exit_code != 0
    assert "--no-bubble 'gyros': choose gyro or accel" in res.output
