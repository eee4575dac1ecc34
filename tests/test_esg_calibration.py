"""The ESG laboratory end to end (issue 6): acquisition, reduction, truth, faults."""

from __future__ import annotations

import json
import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from laboratory.cli import app
from laboratory.esg.calibration import run_esg_calibration
from procedures.esg.acquisition import EsgPlan, plan_slope_per_deg
from procedures.runner import ProcedureError
from sim.esg.world import EsgParams
from station.config.esg import load_esg_params
from station.config.isu import ConfigError

GOAL = 15.0


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("esg")
    return out, run_esg_calibration(1, out)


def test_readout_goal_and_truth(default_run):
    out, res = default_run
    names = [s["name"] for s in res["schedules"]]
    assert names == ["5deg", "1-2-5deg"]
    for s in res["schedules"]:
        assert s["order"] == 7 and s["n_fit"] >= 20 and s["n_readout"] >= 20
        assert s["readout_rms_arcsec"] < GOAL
        assert s["true_readout_rms_arcsec"] < GOAL
        # measured and true differ by the colatitude assignment, whose size we predict
        assert s["assignment_rms_arcsec"] < 2.0 * s["predicted_assignment_rms_arcsec"]
        both = math.hypot(s["readout_rms_arcsec"], 2.5 * s["predicted_assignment_rms_arcsec"])
        assert s["true_readout_rms_arcsec"] < both
    for key in ("sim_seconds", "wall_seconds", "amplification", "schedules"):
        assert key in res
    pts = {(a["pattern"], a["range_deg"], a["strategy"]) for a in res["amplification"]}
    assert ("great_circle", 43.0, "mixed") in pts and ("cosine", 37.0, "mixed") in pts
    for f in ("esg.json", "esg_calibration.png", "esg_strategy.png", "journal.jsonl",
              "sheets/esg_calibration_5deg.json", "sheets/esg_readout_1-2-5deg.json",
              "sheets/check_ESG-CAL.json"):
        assert (out / f).exists(), f
    on_disk = json.loads((out / "esg.json").read_text())
    assert on_disk["schedules"] == res["schedules"]


def test_tables_carry_measured_and_true_errors(default_run):
    out, _ = default_run
    rows = json.loads((out / "sheets" / "esg_readout_5deg.json").read_text())
    for r in rows:
        want = (r["compensated_deg"] - r["colatitude_deg"]) * 3600
        assert r["error_arcsec"] == pytest.approx(want, abs=1e-6)
        want = (r["compensated_deg"] - r["true_colatitude_deg"]) * 3600
        assert r["true_error_arcsec"] == pytest.approx(want, abs=1e-6)
    # the colatitudes cover the pattern on both hemispheres
    cols = [r["colatitude_deg"] for r in rows]
    assert min(cols) < 47 and max(cols) > 133


def test_pickoff_coning_check_sees_the_true_misalignment(default_run):
    _, res = default_run
    a = res["acquisition"]
    assert abs(a["pickoff_coning_arcsec"] - a["true_pickoff_coning_arcsec"]) < 6.0
    # the two equal-ratio points are 180 - 2 theta* apart on the spindle scale
    assert abs(abs(a["equal_points_separation_deg"]) - (180 - 2 * a["theta_star_deg"])) < 0.01


def test_same_seed_same_record(default_run, tmp_path):
    _, res = default_run
    again = run_esg_calibration(1, tmp_path, with_study=False)
    assert again["schedules"] == res["schedules"]
    other = run_esg_calibration(2, tmp_path / "other", with_study=False)
    assert other["schedules"] != res["schedules"]


def _used_lines_match_truth(out: Path, rack, t_zero: float, tol: float) -> int:
    """Every count ratio the reduction used is the noise-free one within ``tol``."""
    n = 0
    for line in (out / "journal.jsonl").read_text().splitlines():
        rec = json.loads(line)
        rd = rec.get("reading")
        if rec.get("kind") != "step" or not isinstance(rd, dict) or "line_cr" not in rd:
            continue
        for p, crs in rd["line_cr"].items():
            for t, cr in zip(rd["times_s"], crs, strict=True):
                truth = rack.world.true_count_ratio(int(p), t + t_zero)
                assert abs(cr - truth) < tol, (rec["chart"], rec["step"], cr, truth)
                n += 1
    return n


def _rejections(out: Path) -> list[str]:
    rej = []
    for line in (out / "journal.jsonl").read_text().splitlines():
        rd = json.loads(line).get("reading")
        if isinstance(rd, dict):
            rej += rd.get("rejected", [])
    return rej


def test_arc_marks_never_reach_the_reduction(tmp_path):
    """Wide arc marks get past the discriminator and mis-gate counts: the per-setting
    check throws those lines out; every line used stays on the noise-free ratio."""
    p = EsgParams()
    p = replace(p, signal=replace(p.signal, arc_rate_per_rev=0.02, arc_wide_fraction=1.0))
    racks = []
    res = run_esg_calibration(3, tmp_path, params=p, rack_hook=racks.append,
                              with_study=False)
    rej = _rejections(tmp_path)
    assert any("off the setting's agreeing lines" in r for r in rej)
    t0 = res_t_zero(tmp_path)
    assert _used_lines_match_truth(tmp_path, racks[0], t0, 6e-5) > 500
    for s in res["schedules"]:
        assert s["true_readout_rms_arcsec"] < GOAL


def res_t_zero(out: Path) -> float:
    for line in (out / "journal.jsonl").read_text().splitlines():
        rec = json.loads(line)
        if rec.get("step") == "DP.1":
            return rec["reading"]["t_zero_s"]
    raise AssertionError("no DP.1 step")


def test_corrupted_lines_are_rejected_with_a_reason(tmp_path):
    racks = []

    def hook(rack):
        rack.processor.corrupt_every = 7
        racks.append(rack)

    res = run_esg_calibration(4, tmp_path, rack_hook=hook, with_study=False)
    for s in res["schedules"]:
        assert s["true_readout_rms_arcsec"] < GOAL
    rej = _rejections(tmp_path)
    assert len(rej) > 30
    assert all(":" in r for r in rej)
    assert any("non-digit" in r for r in rej) and any("period" in r for r in rej)
    assert _used_lines_match_truth(tmp_path, racks[0], res_t_zero(tmp_path), 6e-5) > 500


def test_head_that_stops_answering_stops_the_run_naming_it(tmp_path):
    def hook(rack):
        def silence():
            yield rack.env.timeout(int(7140e9))  # 6200 s before sheet ESG-DPX (940 s)
            rack.head.silent = True

        rack.env.process(silence())

    with pytest.raises(ProcedureError) as e:
        run_esg_calibration(1, tmp_path, rack_hook=hook, with_study=False)
    assert "head" in str(e.value) and "ESG-" in str(e.value)
    steps = [json.loads(x) for x in (tmp_path / "journal.jsonl").read_text().splitlines()]
    done = [r["step"] for r in steps if r.get("kind") == "step"]
    assert "4a" in done and "9.01" in done and "DP.1" in done


def test_config_errors_name_the_field(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[esg.pattern]\nroughness_rms_in = -1\n")
    with pytest.raises(ConfigError, match=r"esg\.pattern\.roughness_rms_in"):
        load_esg_params(bad)
    bad.write_text("[esg]\nspin_rpm = 250\n")
    with pytest.raises(ConfigError, match=r"esg\.spin_rpm"):
        load_esg_params(bad)
    r = CliRunner().invoke(app, ["esg-calibration", "--config", str(bad), "--out",
                                 str(tmp_path / "x")])
    assert r.exit_code == 2 and "spin_rpm" in r.output
    good = tmp_path / "good.toml"
    good.write_text("[esg]\nlatitude_deg = 40.0\n[esg.pattern]\nroughness_rms_in = 2e-5\n")
    p = load_esg_params(good)
    assert p.latitude_deg == 40.0 and p.pattern.roughness_rms_in == 2e-5


def test_predicted_assignment_error_is_honest_over_seeds(tmp_path):
    """Monte Carlo over seeds: the rms of (assigned - true colatitude) against the rms of
    the predicted sigmas (0.98 over seeds 200-223, 0.90 over 1-24; docs/esg.md)."""
    obs, pred = [], []
    for seed in range(200, 208):
        res = run_esg_calibration(seed, tmp_path / str(seed), with_study=False)
        s = res["schedules"][0]
        obs.append(s["assignment_rms_arcsec"])
        pred.append(s["predicted_assignment_rms_arcsec"])
    q = math.sqrt(sum(x * x for x in obs) / sum(x * x for x in pred))
    assert 0.6 < q < 1.6, (q, obs, pred)



def _step(out: Path, number: str) -> dict | None:
    for line in (out / "journal.jsonl").read_text().splitlines():
        rec = json.loads(line)
        if rec.get("kind") == "step" and rec.get("step") == number:
            return rec["reading"]
    return None


def test_equator_slope_is_its_own_tracks_on_a_rough_pattern(tmp_path):
    """Edge roughness drawn at 12-25 times the default (up to the loader's bound) bends the
    count ratio on the scale of its correlation. Step 7 reads the slope of the equator's
    own track (beyond the report): within 4 sigma of the true secant over the same span,
    where the drawing's slope, which carried the drift before, is tens of sigma off. The
    runs that complete keep their predicted assignment error (pooled within 0.5-2)."""
    rng = np.random.default_rng(20261128)
    z, z_drawing, obs, pred = [], [], [], []
    for seed in range(300, 310):
        rough = float(rng.uniform(5e-4, 1e-3))
        params = replace(EsgParams(), pattern=replace(EsgParams().pattern,
                                                      roughness_rms_in=rough))
        racks: list = []
        out = tmp_path / str(seed)
        try:
            res = run_esg_calibration(seed, out, params=params, rack_hook=racks.append,
                                      with_study=False)
            s = res["schedules"][0]
            obs.append(s["assignment_rms_arcsec"])
            pred.append(s["predicted_assignment_rms_arcsec"])
        except ProcedureError:
            pass  # steps 3.4 and 4 stop some of these rotors (docs/esg.md)
        r7 = _step(out, "7")
        if r7 is None:
            continue
        w, t = racks[0].world, r7["t_s"] + res_t_zero(out)
        th = math.degrees(float(w.true_colatitudes(t)[1]))
        cr = [w.pattern.count_ratio(math.radians(th + d)) for d in (-0.05, 0.05)]
        true = (cr[1] - cr[0]) / 0.1  # per degree of colatitude
        sigma = 9e-6 / math.sqrt(5) * math.sqrt(2.0) / 0.1  # two settings' mean ratios
        z.append((abs(r7["slope_eq_per_deg"]) - abs(true)) / sigma)
        z_drawing.append((abs(plan_slope_per_deg(90.0, EsgPlan(0.0))) - abs(true)) / sigma)
    assert len(z) >= 6, z
    assert max(abs(x) for x in z) < 4.0, z
    assert max(abs(x) for x in z_drawing) > 10.0, z_drawing
    assert len(obs) >= 4, obs
    q = math.sqrt(sum(x * x for x in obs) / sum(x * x for x in pred))
    assert 0.5 < q < 2.0, (q, obs, pred)


def test_a_tilt_that_does_not_reach_the_equator_stops_the_run_naming_it(tmp_path):
    """Steps 8 and 10-12 tilt pickoff 1 onto the equator's count ratio; a tilt left off it
    puts the spin axis out of the scan's plane and every colatitude of the scan wrong
    (seen as 1-2 deg errors against a 30-arcsec sigma before the check). With no tilt
    iterations allowed the run stops at step 8 by name, the steps before it kept."""
    out = tmp_path / "r"
    with pytest.raises(ProcedureError, match=r"step 8 .*pickoff 1 still reads \S+ from the "
                       r"equator's count ratio after 0 tilts \(at most 2\.4e-05\)"):
        run_esg_calibration(1, out, plan=EsgPlan(latitude_deg=0.0, search_iterations=0),
                            with_study=False)
    assert _step(out, "7") is not None


def test_a_cosine_pattern_ending_past_45_deg_gates_on_the_equators_logic_time(tmp_path):
    """On a cosine rotor whose lines end at 51 deg the logic-to-line time is longer at the
    equator than at the extremity: ESG-DPX's delay covers the longer one (with the
    extremity's alone, step 3 found no line-1 edges on every seed tried)."""
    from station.config.esg import EsgConfig, params_from

    params = params_from(EsgConfig.model_validate(
        {"pattern": {"kind": "cosine", "top_colatitude_deg": 51.0}}))
    out = tmp_path / "r"
    res = run_esg_calibration(4, out, params=params, with_study=False)
    dpx = json.loads((out / "sheets" / "check_ESG-DPX.json").read_text())
    r4 = next(s for s in dpx["steps"] if s["number"] == "DPX.4")["reading"]
    assert r4["equator_logic_to_line_us"] > r4["logic_to_line_us"]
    assert r4["set_us"] == math.ceil(r4["equator_logic_to_line_us"] + 20.0)
    s = res["schedules"][0]
    assert s["assignment_rms_arcsec"] < 3.0 * s["predicted_assignment_rms_arcsec"]


def _random_lab(rng: np.random.Generator) -> dict:
    """An ESG laboratory drawn inside the loader's bounds, where the procedure completes:
    electric torque up to 0.3 deg/h, jitter up to 1000 ns, rundown 25 h and longer
    (log-uniform; beyond those, steps 3, 4a and 4b stop by name: docs/esg.md)."""
    top = float(rng.uniform(38.0, 53.7))
    return {"latitude_deg": float(rng.uniform(-80, 80)),
            "spin_rps": float(rng.uniform(250, 400)),
            "rundown_tau_h": float(math.exp(rng.uniform(math.log(25.0), math.log(1000.0)))),
            "unbalance_dyne_cm": float(rng.uniform(2, 60)),
            "electric_deg_h": float(rng.uniform(0, 0.3)),
            "damping_tau_s": float(rng.uniform(10, 300)),
            "pattern": {"top_colatitude_deg": top,
                        "inclination_deg": float(rng.uniform(max(56.0, 100.0 - top), 79.5)),
                        "application_in": float(rng.uniform(0, 0.001)),
                        "roughness_rms_in": float(rng.uniform(0, 2e-4)),
                        "d0_sd_in": float(rng.uniform(0, 0.005))},
            "signal": {"jitter_ns": float(rng.uniform(40, 1000)),
                       "arc_rate_per_rev": float(rng.uniform(0, 3))}}


def test_random_laboratories_keep_their_predicted_assignment_error(tmp_path):
    """Sites, rotors, patterns and pickoff jitter drawn at random: the procedure takes its
    agreement, step-4 spread, tilt-probe and step-3 drift-wait figures from the lab's line
    scatter (sqrt(2 / revolutions) jitter spin) and judges step 3's drift without the
    rundown's share, so a noisier or faster-running-down lab completes with a larger
    sigma that is still honest (bench: 14 of 16 labs, seeds 500-515, pooled 0.93; before,
    rundown under about 50 h or jitter over about 400 ns stopped at step 3.4). Stops are
    by name at a step; the completed runs pool within 0.6-1.6."""
    from station.config.esg import EsgConfig, params_from

    obs, pred, stops = [], [], []
    for seed in range(505, 515):
        cfg = _random_lab(np.random.default_rng(seed))
        try:
            res = run_esg_calibration(seed, tmp_path / str(seed),
                                      params=params_from(EsgConfig.model_validate(cfg)),
                                      with_study=False)
        except ProcedureError as e:
            assert re.search(r"step \d", str(e)), e
            stops.append(str(e))
            continue
        s = res["schedules"][0]
        obs.append(s["assignment_rms_arcsec"])
        pred.append(s["predicted_assignment_rms_arcsec"])
    assert len(obs) >= 8, stops
    q = math.sqrt(sum(x * x for x in obs) / sum(x * x for x in pred))
    assert 0.6 < q < 1.6, (q, obs, pred)
    assert max(pred) > 2.0 * min(pred), pred  # the labs differ: the sigmas follow them


def test_step_3_waits_longer_in_a_noisier_lab():
    """Step 3's drift is two settings' difference over the wait: the plan keeps three
    sigmas of it at half the 0.1 deg/h tolerance, so the report's 600 s holds at the
    default lab (which would need about 330 s), a noisier lab waits in proportion to its
    line scatter, up to an hour."""
    from procedures.esg.acquisition import MAX_DRIFT_WAIT_S

    plan = EsgPlan(latitude_deg=40.0)
    assert plan.drift_wait == plan.drift_wait_s == 600.0
    slope = abs(plan_slope_per_deg(90.0, plan))
    waits = []
    for jitter_ns in (300.0, 500.0, 700.0):
        p = replace(plan, line_scatter_spec=9e-6 * jitter_ns / 80.0)
        sigma_rate = math.sqrt(2.0) * p.setting_sigma / slope / (p.drift_wait / 3600.0)
        assert 3.0 * sigma_rate == pytest.approx(0.5 * p.drift_tolerance_deg_hr)
        waits.append(p.drift_wait)
    assert waits == sorted(waits) and waits[0] > 600.0
    noisy = replace(plan, line_scatter_spec=9e-6 * 5000.0 / 80.0)
    assert noisy.drift_wait == MAX_DRIFT_WAIT_S


def test_step_3_does_not_chase_the_rundown(tmp_path):
    """A rotor running down in 30 h (the default 88): its unbalance drift grows as the
    spin falls, about 0.17 deg/h in one of step 3's offsets, so every re-measured drift
    was over the 0.1 deg/h tolerance and the run stopped at step 3.4. The drift the
    rundown added since the last offset (k times the growth of the spin period's count
    the lines carry) is now left to the scans' interpolation; the drift left beside it is
    within the tolerance, the measured drift agrees with that share, and the run
    completes with an honest assignment error."""
    from station.config.esg import EsgConfig, params_from

    params = params_from(EsgConfig.model_validate({"rundown_tau_h": 30.0}))
    obs, pred = [], []
    for seed in (1, 2, 3):
        out = tmp_path / str(seed)
        res = run_esg_calibration(seed, out, params=params, with_study=False)
        s = res["schedules"][0]
        obs.append(s["assignment_rms_arcsec"])
        pred.append(s["predicted_assignment_rms_arcsec"])
        last = None
        for it in range(2, 5):
            last = _step(out, f"3.{it}") or last
        assert last is not None and last["within_tolerance"], last
        assert last["rundown_drift_deg_hr"] < -0.1  # the rundown's share, same sign as k's
        assert abs(last["east_drift_deg_hr"] - last["rundown_drift_deg_hr"]) <= 0.1, last
    q = math.sqrt(sum(x * x for x in obs) / sum(x * x for x in pred))
    assert 0.5 < q < 1.8, (q, obs, pred)
