"""Alignment (report 000 Part I Section 3 and Part III).

(a) The T convention proven against the simulator's true attitude: Charts III-3, III-7 and
    III-11 fed with the true mirror normals, g and Earth rate give world.attitude(t)^T, and
    ``rotation_error`` reads a known turn with its sign.
(b) Preprocessing (Charts III-5, III-9) inverts the instrument models of the simulator.
(c) The day's alignments (all three methods, both techniques) on one seed: every error
    within 4 predicted sigmas, every predicted sigma within a factor 2 of its physical limit,
    the posterior mean's predicted error below the average's, sheets and tapes recorded.
(d) Lost IEU frames: recovered by RESEND (T identical to the run without loss); stopped
    with a ProcedureError naming Chart III-4 step 9 when the IEU cannot resend, or when
    recovery is off.
(e) A tape for another experiment stops Chart III-4 step 8 naming the parameter.
(f) `station align` writes results.json with the alignment list.
(g) The results are checked against the mirror alignment and the site: a constant 30 sigma
    off stops the level or gyrocompass alignment naming what it contradicts.
"""

from __future__ import annotations

import json
import math
from collections import deque

import numpy as np
import pytest
from rich.console import Console

from config.dbc import load_dbc
from laboratory.isu.align import (
    AlignRequest,
    alignment_entries,
    day_alignments,
    day_methods,
    run_align,
)
from laboratory.isu.spec import noise_spec, site_of
from laboratory.isu.truth import calibration_truth
from laboratory.pytest_plugin import assert_within_sigma
from procedures.isu.alignment import align_math as am
from procedures.isu.alignment.options import AlignmentOptions
from procedures.isu.alignment.parameter_sheet import write_tape
from procedures.isu.alignment.preprocess import Constants, accel_integrals, gyro_integrals
from procedures.isu.alignment.results_sheet import AlignPlan
from procedures.isu.alignment.run import run_alignments
from procedures.isu.computations import compute_calibration
from procedures.isu.day import measure_day
from procedures.isu.plan import DayPlan
from procedures.isu.sheets import CalibrationResults, ResultRow
from procedures.isu.turn_on import turn_on
from procedures.journal import Journal
from procedures.runner import ProcedureError, Run
from sim import units
from station.config.isu import load_config
from station.racks.isu import SimulatedRack, open_isu_drivers

QUIET = Console(quiet=True)
SEED = 2024
ARCSEC = math.pi / (180 * 3600)
SHORT = AlignPlan(level_K=20, level_dt_s=2.0, mirror_readings=2, alpha_readings=2)


# ----------------------------------------------------------------------------- (a) convention
@pytest.fixture
def at_position0(station):
    for ax, deg in enumerate((0.0, 90.0, 90.0, 0.0), start=1):
        station.table.move(ax, deg)
    station.table.wait_still()
    station.clock.sleep(5.0)
    return station


def test_t_convention_round_trip_against_true_attitude(rack, at_position0):
    w = rack.world
    t = w.now
    t_true = w.attitude(t).T  # T = T^EB: columns are the body axes in (U, E, N)
    m1, m2 = w.mirror_normals(t)
    ac = [*am_angles(m1), *am_angles(m2)]
    assert np.allclose(am.mirror_alignment(*ac), t_true, atol=1e-12)
    # Chart III-3's first column is (U.M1, E.M1, N.M1) as printed
    assert np.allclose(t_true[:, 0], m1, atol=1e-12)
    g_b = w.attitude(t) @ w.site.gravity_e / units.G0  # g in body axes, g units
    w_b = w.attitude(t) @ w.site.earth_rate_e / units.deg_per_hr(1.0)  # deg/hr
    assert np.allclose(am.level_matrix(g_b, ac[0]), t_true, atol=1e-12)
    assert np.allclose(am.gyrocompass_matrix(g_b, w_b), t_true, atol=1e-12)
    # the report's optional inputs, given their exact values, change nothing
    colat = math.degrees(w.site.colatitude)
    gm, wm = float(np.linalg.norm(g_b)), float(np.linalg.norm(w_b))
    assert np.allclose(am.level_matrix(g_b, ac[0], theta1_deg=ac[1], g_survey=gm), t_true,
                       atol=1e-12)
    assert np.allclose(am.gyrocompass_matrix(g_b, w_b, colatitude_deg=colat, g_survey=gm,
                                             w_survey=wm), t_true, atol=1e-9)
    # the B axes in earth components at position 0: B1 near east, B2 near north, B3 up
    assert np.allclose(t_true, [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=0.02)
    # rotation_error: the truth turned by +10 arcsec about up (east towards north) and
    # by -3 arcsec about east reads as such
    turn = am_rotation((1, 0, 0), 10 * ARCSEC) @ am_rotation((0, 1, 0), -3 * ARCSEC)
    err = am.rotation_error_arcsec(turn @ t_true, t_true)
    assert err == pytest.approx({"azimuth": 10.0, "east": -3.0, "north": 0.0}, abs=1e-3)


def am_angles(m) -> tuple[float, float]:
    """(azimuth from east towards north, zenith) of a unit vector (U, E, N), degrees."""
    return math.degrees(math.atan2(m[2], m[1])), math.degrees(math.acos(m[0]))


def am_rotation(axis, angle) -> np.ndarray:
    k = np.asarray(axis, float)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx


# ----------------------------------------------------------------------------- (b) preprocessing
def truth_constants(world) -> Constants:
    return Constants(calibration_truth(world))


def test_preprocessing_inverts_the_instrument_models(rack):
    w = rack.world
    c = truth_constants(w)
    rng = np.random.default_rng(1)
    K, dt = 5, np.full(5, 2.0)
    a_b = rng.normal(0, 0.5, (K, 3)) * units.G0  # m/s^2, body
    w_b = rng.normal(0, 1.0, (K, 3)) * units.deg_per_hr(15.0)  # rad/s
    p_a = np.column_stack([a.difference_rate(a_b) for a in w.isu.accels]) * dt[:, None]
    p_g = np.column_stack([g.rate(w_b, a_b) / g.dphi for g in w.isu.gyros]) * dt[:, None]
    int_b, _, u = accel_integrals(p_a, dt, c)
    assert np.allclose(int_b, a_b / units.G0 * dt[:, None], atol=2e-6)
    int_w = gyro_integrals(p_g, dt, u, c)
    # int w.B dt in arcsec (deg/hr x s). Chart III-9 takes a.G, a.O, a.S along the nominal
    # axes, so terms of (misalignment ~1e-3) x (B ~1 deg/hr/g) x (|a| < 2 g) remain: under
    # 0.005 deg/hr, below the calibration's own sigmas of R and B (0.006-0.007 deg/hr)
    want = w_b / units.deg_per_hr(1.0) * dt[:, None]
    assert np.allclose(int_w, want, atol=0.005 * 2.0)


# ----------------------------------------------------------------------------- (c) the day
@pytest.fixture(scope="module")
def day(tmp_path_factory):
    out = tmp_path_factory.mktemp("align_day")
    cfg = load_config(seed=SEED)
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    try:
        run = Run(st.clock, Journal(out / "journal.jsonl"))
        plan = DayPlan()
        site = site_of(cfg)
        data = measure_day(st, run, plan, site, cfg.isu.accels[0].f0_hz)
        calib = compute_calibration(run, data, plan, noise_spec(cfg), site)
        entries = day_alignments(st, run, calib, cfg, rack.world, tape_dir=out / "tapes")
        yield {"out": out, "entries": entries, "calib": calib, "run": run,
               "survey": data.survey, "cfg": cfg}
    finally:
        st.close()
        rack.close()


def test_day_alignments_within_predicted_error(day):
    entries = day["entries"]
    got = [(e["method"], e["estimator"]) for e in entries]
    assert got == [("mirror", "average"), ("level", "average"), ("level", "posterior"),
                   ("gyrocompass", "average"), ("gyrocompass", "hybrid")]
    for e in entries:
        err = [*e["level_error_arcsec"], e["azimuth_error_arcsec"]]
        sig, lim = e["predicted_sigma_arcsec"], e["physical_limit_arcsec"]
        for x, s, li in zip(err, sig, lim, strict=True):
            assert abs(x) < 4 * s, e
            assert 0.5 < s / li < 2.0, e
        assert isinstance(e["K"], int) and e["K"] >= 1 and e["dt"] > 0
    by = {(e["method"], e["estimator"]): e for e in entries}
    # the levels: about 1-2 arcsec (accelerometer bias and misalignment over g), the
    # gyrocompass azimuth about 4 arcmin (gyro bias over 11 deg/hr of horizontal Earth rate)
    assert by[("level", "average")]["predicted_sigma_arcsec"][0] < 3.0
    assert 100 < by[("gyrocompass", "average")]["predicted_sigma_arcsec"][2] < 400
    assert by[("mirror", "average")]["predicted_sigma_arcsec"][2] < 0.5
    for m, a, p in (("level", "average", "posterior"), ("gyrocompass", "average", "hybrid")):
        for i in (0, 1):
            assert by[(m, p)]["predicted_sigma_arcsec"][i] < by[(m, a)][
                "predicted_sigma_arcsec"][i]


def test_day_records_sheets_and_tapes(day):
    run = day["run"]
    for name in ("alignment_results_mirror", "alignment_results_level_average",
                 "alignment_results_level_posterior", "alignment_results_gyrocompass_average",
                 "alignment_results_gyrocompass_hybrid", "alignment_parameters_level",
                 "alignment_parameters_gyrocompass", "check_III-2", "check_III-4",
                 "check_III-8", "check_I-7"):
        assert name in run.sheets, name
    sheet = run.sheets["alignment_results_level_posterior"]
    assert sheet.K == 150 and sheet.dt_s == 2.0
    assert sheet.filtering_parameter_id == run.sheets["alignment_parameters_level"].reel_id
    tapes = sorted(p.name for p in (day["out"] / "tapes").iterdir())
    assert len(tapes) == 2
    steps = [s.number for s in run.check_sheets["III-4"].steps]
    assert steps == ["1", "1a", "2", "3", "4", "5", "6", "7", "8", "9", "10", "11", "12"]
    assert [s.number for s in run.check_sheets["III-8"].steps] == [
        "1", "1a", "2", "3", "4", "5", "6", "7", "8", "9", "10"]


# ----------------------------------------------------------------------------- (d) lost frames
def _level_run(day, tmp_path, hook=None, plan=SHORT):
    cfg = day["cfg"]
    rack = SimulatedRack(cfg)
    if hook:
        hook(rack)
    st = open_isu_drivers(cfg, rack)
    try:
        run = Run(st.clock, Journal(tmp_path / "j.jsonl"))
        turn_on(st, run, 60.0)
        oc = run_alignments(st, run, AlignmentOptions(
            noise_spec(cfg), day["calib"], day["survey"], site_of(cfg), plan,
            estimators={"level": ("average",)}))
        return oc[0], run
    finally:
        st.close()
        rack.close()


def test_lost_ieu_frames_are_recovered(day, tmp_path):
    clean, _ = _level_run(day, tmp_path / "a")

    def drop(rack):
        rack.ieu.drop_every = 7

    (tmp_path / "b").mkdir()
    lossy, run = _level_run(day, tmp_path / "b", drop)
    assert lossy.detail["recovered"], "frames were dropped: recoveries expected"
    assert np.array_equal(lossy.t, clean.t)  # the same counts: the same T
    assert lossy.t_ref == pytest.approx(clean.t_ref, abs=1e-3)
    rec = next(s for s in run.check_sheets["III-4"].steps if s.number == "9").reading
    assert rec["recovered_samples"] == lossy.detail["recovered"]


@pytest.mark.parametrize("case", ["history-gone", "recovery-off"])
def test_unrecoverable_loss_stops_the_step(day, tmp_path, case):
    def drop(rack):
        rack.ieu.drop_every = 7
        if case == "history-gone":
            rack.ieu.history_len = 0

    plan = SHORT if case == "history-gone" else SHORT.model_copy(
        update={"recover_lost_samples": False})
    with pytest.raises(ProcedureError) as e:
        _level_run(day, tmp_path, drop, plan)
    assert (e.value.chart, e.value.step) == ("III-4", "9")
    assert "Chart III-4, step 9" in str(e.value)
    assert ("RESEND refused" if case == "history-gone" else "lost frame") in str(e.value)


# ----------------------------------------------------------------------------- (g) checks
def _shifted(calib: CalibrationResults, inst: str, par: str, n_sigma: float
             ) -> CalibrationResults:
    rows = [r.model_copy(update={"estimate": r.estimate + n_sigma * r.sigma})
            if (r.instrument, r.parameter) == (inst, par) else r for r in calib.rows]
    return CalibrationResults(rows=rows, positions_used=calib.positions_used)


def _run_with(day, tmp_path, calib, estimators):
    cfg = day["cfg"]
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    try:
        run = Run(st.clock, Journal(tmp_path / "j.jsonl"))
        turn_on(st, run, 60.0)
        return run_alignments(st, run, AlignmentOptions(
            noise_spec(cfg), calib, day["survey"], site_of(cfg), SHORT,
            estimators=estimators)), run
    finally:
        st.close()
        rack.close()


@pytest.mark.parametrize(("method", "inst", "par", "step"), [
    ("level", "accel1", "D0", "12"),  # 30 sigma of bias: about 21 arcsec of tilt
    ("gyrocompass", "gyro1", "R", "10"),  # 30 sigma of drift: about an hour of azimuth
])
def test_a_wrong_constant_stops_the_alignment_against_the_mirror(day, tmp_path, method,
                                                                 inst, par, step):
    """The day's calibration gives alignments that agree with the mirror alignment and the
    site (every check recorded); one constant off by 30 sigma stops the alignment's last
    step naming what it contradicts."""
    est = {"mirror": ("average",), method: ("average",)}
    (tmp_path / "a").mkdir()
    _, run = _run_with(day, tmp_path / "a", day["calib"], est)
    chart = "III-4" if method == "level" else "III-8"
    rec = next(s for s in run.check_sheets[chart].steps if s.number == step).reading
    checks = rec["average"]["checks"]
    assert {"about east", "about north", "about up (azimuth)"} <= set(checks)
    assert all(abs(c["z"]) < 6.0 for c in checks.values())
    (tmp_path / "b").mkdir()
    with pytest.raises(ProcedureError) as e:
        _run_with(day, tmp_path / "b", _shifted(day["calib"], inst, par, 30.0), est)
    assert (e.value.chart, e.value.step) == (chart, step)
    assert f"{method} alignment (average): T about " in str(e.value)
    assert "the mirror alignment (Chart III-2)" in str(e.value)


# ----------------------------------------------------------------------------- (e) tapes
def test_tape_for_another_experiment_is_refused(day, tmp_path):
    cfg = day["cfg"]
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    try:
        run = Run(st.clock, Journal(tmp_path / "j.jsonl"))
        turn_on(st, run, 60.0)
        noise, site = noise_spec(cfg), site_of(cfg)
        from procedures.isu.alignment.common import calibration_constants, experiment_params
        from procedures.isu.alignment.parameter_evaluation import parameter_evaluation

        c = calibration_constants(day["calib"], gyros=False)
        other = SHORT.model_copy(update={"level_K": 25})
        tapes = parameter_evaluation(
            run, {"level": (experiment_params(other, noise, day["survey"], c, 25, 2.0), "x")})
        write_tape(tapes["level"], tmp_path / "tape.json")
        with pytest.raises(ProcedureError) as e:
            run_alignments(st, run, AlignmentOptions(
                noise, day["calib"], day["survey"], site, SHORT,
                estimators={"level": ("posterior",)}, tapes=tapes))
        assert (e.value.chart, e.value.step) == ("III-4", "8")
        assert "tape parameter K differs" in str(e.value)
    finally:
        st.close()
        rack.close()


def _without(calib: CalibrationResults, inst: str, par: str) -> CalibrationResults:
    rows = [r for r in calib.rows if not (r.instrument == inst and r.parameter == par)]
    rows.append(ResultRow(instrument=inst, parameter=par, units="", estimate=None,
                          sigma=None, positions="7-12"))
    return CalibrationResults(rows=rows, positions_used=[])


def test_day_runs_the_alignments_a_partial_calibration_allows(day):
    assert list(day_methods(day["calib"])) == ["mirror", "level", "gyrocompass"]
    assert list(day_methods(_without(day["calib"], "gyro1", "R"))) == ["mirror", "level"]
    assert list(day_methods(_without(day["calib"], "accel3", "D3"))) == ["mirror"]


def test_missing_calibration_constants_stop_step_6(day, tmp_path):
    partial = _without(day["calib"], "accel2", "D0")
    cfg = day["cfg"]
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    try:
        run = Run(st.clock, Journal(tmp_path / "j.jsonl"))
        turn_on(st, run, 60.0)
        with pytest.raises(ProcedureError) as e:
            run_alignments(st, run, AlignmentOptions(
                noise_spec(cfg), partial, day["survey"], site_of(cfg), SHORT,
                estimators={"level": ("average",)}))
        assert (e.value.chart, e.value.step) == ("III-4", "6")
        assert "accel2 D0" in str(e.value)
    finally:
        st.close()
        rack.close()


# ----------------------------------------------------------------------------- (f) station align
def test_station_align_writes_results(day, tmp_path, station_lab, run_procedure):
    """Through the station's pytest plugin: `align`'s run function on a virtual ISU station
    of seed 7, after the module's calibration."""
    cal = tmp_path / "cal"
    (cal / "sheets").mkdir(parents=True)
    (cal / "sheets" / "calibration_results.json").write_text(day["calib"].model_dump_json())
    (cal / "sheets" / "survey_results.json").write_text(day["survey"].model_dump_json())
    rec = run_procedure("align", station_lab("isu", seed=7), out=tmp_path / "out",
                        method="mirror", estimator="average", calibration=cal, warmup_s=60.0)
    saved = rec.results
    assert saved["alignment"] == json.loads(json.dumps(rec.returned["alignment"]))
    (e,) = saved["alignment"]
    for key, kind in (("method", str), ("estimator", str), ("K", int), ("dt", float),
                      ("level_error_arcsec", list), ("azimuth_error_arcsec", float),
                      ("predicted_sigma_arcsec", list), ("physical_limit_arcsec", list)):
        assert isinstance(e[key], kind), key
    assert "alignment_results_mirror" in rec.sheets
    errors = [*e["level_error_arcsec"], e["azimuth_error_arcsec"]]
    for axis, x, s in zip("ENA", errors, e["predicted_sigma_arcsec"], strict=True):
        assert_within_sigma(x, 0.0, s, k=4, name=f"mirror alignment error {axis}")


def test_alignment_entries_read_the_truth_at_t_ref(day):
    e = day["entries"][0]
    assert np.allclose(np.array(e["T"]) @ np.array(e["T_true"]).T, np.eye(3), atol=1e-5)
    assert alignment_entries([], None) == []


class _Mangle(deque):
    """IEU output that garbles (truncates) the n-th frame with one identifier."""

    def __init__(self, frame_id: int, nth: int) -> None:
        super().__init__()
        self.frame_id, self.nth, self.seen = frame_id, nth, 0

    def append(self, item) -> None:
        t, fid, data = item
        if fid == self.frame_id:
            self.seen += 1
            if self.seen == self.nth:
                data = data[:2]
        super().append((t, fid, data))


def _samples(cfg, n: int, hook=None) -> tuple[list, object]:
    rack = SimulatedRack(cfg)
    if hook:
        hook(rack)
    st = open_isu_drivers(cfg, rack)
    try:
        st.ieu.start(1000, recover=True)
        got = [st.ieu.next_sample(timeout=1.0) for _ in range(n)]
        st.ieu.stop()
        return [(s.seq, s.gyro, s.accel, s.timer) for s in got], (st.ieu.recoveries,
                                                                   st.ieu.garbled)
    finally:
        st.close()
        rack.close()


def test_driver_recovers_dropped_and_garbled_frames(cfg):
    clean, _ = _samples(cfg, 30)
    accel_a = load_dbc().get_message_by_name("IEU_ACCEL_A").frame_id

    def faults(rack):
        rack.ieu.drop_every = 6
        rack.ieu.output = _Mangle(accel_a, 10)

    got, (recoveries, garbled) = _samples(cfg, 30, faults)
    assert got == clean  # every count recovered, in sequence
    assert garbled == 1
    seqs = [r["seq"] for r in recoveries]  # the drops, and the garbled frame's sample
    assert len(seqs) == 6 and {5, 11, 17, 23, 29} < set(seqs)
    assert {tuple(r["missing"]) for r in recoveries} == {("IEU_GYRO",), ("IEU_ACCEL_A",)}


def test_station_align_uses_a_tape_from_an_earlier_run(day, tmp_path):
    cal = tmp_path / "cal"
    (cal / "sheets").mkdir(parents=True)
    (cal / "sheets" / "calibration_results.json").write_text(day["calib"].model_dump_json())
    (cal / "sheets" / "survey_results.json").write_text(day["survey"].model_dump_json())
    tapes = {p.name.split("-")[0]: p for p in (day["out"] / "tapes").iterdir()}
    res = run_align(AlignRequest(load_config(seed=8), tmp_path / "ok", "level", "posterior",
                                 calibration=cal, tape=tapes["level"], quiet=True,
                                 warmup_s=60.0), QUIET)
    (e,) = res["alignment"]
    assert (e["method"], e["estimator"], e["K"], e["dt"]) == ("level", "posterior", 150, 2.0)
    assert max(abs(x) for x in e["error_over_sigma"]) < 4
    assert not (tmp_path / "ok" / "tapes").exists()  # the tape given was used, none made
    # the gyrocompass's tape (K = 120, dt = 5 s) for a level alignment: refused naming K
    # before anything is written
    with pytest.raises(ValueError, match="tape parameter K differs from the experiment's: "
                                         "tape 120, experiment 150"):
        run_align(AlignRequest(load_config(seed=8), tmp_path / "bad", "level", "posterior",
                               calibration=cal, tape=tapes["gyrocompass"], quiet=True,
                               warmup_s=60.0), QUIET)
    assert not (tmp_path / "bad").exists()
