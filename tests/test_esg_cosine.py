"""A cosine-pattern rotor (report 004, "Pattern Analysis": the alternative pattern, optimum
range 37 deg) through the acquisition and the reduction (docs/esg-options.md)."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from laboratory.esg.calibration import drawing, run_esg_calibration
from procedures.esg.cosine import CosineParams, cosine_cos, cosine_count_ratio, fit_cosine
from procedures.esg.mechanization import nominal_colatitude
from sim.esg import EsgParams
from sim.esg.pattern import Pattern, PatternSpec

THETA_STAR = math.degrees(math.acos(1.0 / math.sqrt(3.0)))


def _smooth(top: float, seed: int) -> Pattern:
    """A cosine rotor with its set-up offset but no application error or roughness."""
    spec = PatternSpec(kind="cosine", top_colatitude_deg=top, application_in=0.0,
                       roughness_rms_in=0.0)
    return Pattern(spec, seed=seed)


@pytest.mark.parametrize(("top", "seed"), [(37.0, 1), (33.0, 4), (45.0, 9)])
def test_mechanization_is_the_rotor_geometry(top, seed):
    """With no application error the cosine mechanization is the simulated rotor's count
    ratio exactly, and the two equal-ratio points give back its K and d0."""
    pat = _smooth(top, seed)
    p = CosineParams(pat.k, pat.d0)
    th = np.linspace(top + 0.1, 180.0 - top - 0.1, 301)
    cr = pat.count_ratio(np.radians(th))
    assert np.max(np.abs(cosine_count_ratio(th, p) - cr)) < 1e-12
    assert np.max(np.abs(np.degrees(np.arccos(cosine_cos(cr, p))) - th)) < 1e-8
    assert np.max(np.abs(nominal_colatitude(cr, p) - th)) < 1e-8  # dispatch
    fit = fit_cosine(float(pat.count_ratio(math.radians(THETA_STAR))),
                     float(pat.count_ratio(math.radians(180.0 - THETA_STAR))), THETA_STAR)
    assert fit.k == pytest.approx(pat.k, rel=1e-12)
    assert fit.d0 == pytest.approx(pat.d0, rel=1e-9, abs=1e-15)


def test_ratio_falls_with_colatitude_and_the_fit_refuses_a_great_circle_pair():
    p = CosineParams(1.0, 0.0)
    assert cosine_count_ratio(50.0, p) < 0.5 < cosine_count_ratio(130.0, p)
    with pytest.raises(ValueError, match="cosine pattern"):
        fit_cosine(0.66, 0.34, THETA_STAR)


def test_drawing_keeps_the_report_plan():
    """The default rotor's drawing is the plan the report's run always had."""
    d = drawing(PatternSpec())
    assert d == {"pattern_kind": "great_circle", "design_inclination_deg": 56.0,
                 "design_cosine_k": 0.0, "design_top_deg": 43.0, "scan_end_deg": 46}
    c = drawing(PatternSpec(kind="cosine", top_colatitude_deg=37.0))
    assert c["scan_end_deg"] == 52 and c["design_cosine_k"] > 0.0


@pytest.mark.parametrize(("seed", "top"), [(2, 37.0), (7, 40.0)])
def test_cosine_rotor_calibrates_within_the_goal(tmp_path, seed, top):
    """The whole calibration on a cosine rotor: the searches find the equal ratios and the
    equator, the reduction's K is the rotor's, and both schedules read out within the
    15 arcsec goal against the simulator's colatitudes; scan points where the logic gate
    met another line were refused, never fitted."""
    params = replace(EsgParams(), pattern=PatternSpec(kind="cosine", top_colatitude_deg=top))
    res = run_esg_calibration(seed, tmp_path, params=params, with_study=False)
    from sim.esg.pattern import nominal_pattern

    assert res["nominal"]["kind"] == "cosine"
    assert res["nominal"]["k"] == pytest.approx(nominal_pattern(params.pattern).k, rel=2e-3)
    for sched in res["schedules"]:
        assert sched["true_readout_rms_arcsec"] < sched["limit"], sched["name"]
        assert sched["true_calibration_rms_arcsec"] < sched["limit"], sched["name"]
    fitted = {(r["scan"], r["offset_deg"])
              for name in ("5deg", "1-2-5deg")
              for r in json.loads((tmp_path / "sheets" / f"esg_calibration_{name}.json")
                                  .read_text())}
    for line in (tmp_path / "journal.jsonl").read_text().splitlines():
        j = json.loads(line)
        if j.get("kind") == "step" and "refused" in j.get("reading", {}):
            scan = j["step"].split(".")[0]
            assert (scan, j["reading"]["offset_deg"]) not in fitted
