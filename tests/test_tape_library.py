"""The tape library and the alignment options of Part III.

(a) The library files a reel, finds it again for the same Chart I-8 parameters (T1 and g~
    within a quarter of their sigmas, everything else to round-off), says why it finds
    none, rebuilds a lost or stale index and does not offer a run its own reels.
(b) Two days of one unit (different seeds, a site and noise drawn at random): the first makes
    and files the tapes, the second finds and uses them (Chart I-7 stops at the lookup) and
    its alignments are within 4 sigma of the truth; `station align --tape` with another K is
    refused naming K before anything is written; through the library another K files a new
    reel.
(c) The three ways of I-3.1 to the nominal T1, the [alignment] table and the command line's
    options, with one-line refusals naming the option.
"""

from __future__ import annotations

import json
import random
import subprocess
import sys

import numpy as np
import pytest
from rich.console import Console
from scipy.spatial.transform import Rotation

from laboratory.isu.align import AlignRequest, command_plan, run_align
from laboratory.isu.day import DayRequest, run_day
from laboratory.pytest_plugin import virtual_station
from procedures.isu.alignment.estimation import level_params_from_noise_spec
from procedures.isu.alignment.parameter_sheet import AlignmentParameterSheet, make_tape
from procedures.isu.alignment.tape_library import INDEX, TapeLibrary
from procedures.isu.calibration.noise_spec import NoiseSpec

QUIET = Console(quiet=True)
ARCSEC = np.pi / 180.0 / 3600.0


# ------------------------------------------------------------------------------------ (a)
T1 = Rotation.from_rotvec([0.01, -0.02, 1.5]).as_matrix()


def _params(**update):
    p = level_params_from_noise_spec(NoiseSpec(), 1.0, 5, g_tilde=9.80382, sigma_g=1e-2, T1=T1,
                                     sigma_theta=60 * ARCSEC, eps_t=0.5,
                                     vibration_max_lag_s=2.0)
    return p.model_copy(update=update) if update else p


def _turned(params, angle_rad: float):
    axis = np.array([0.3, -0.5, 0.8])
    r = Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle_rad).as_matrix()
    return tuple(tuple(float(x) for x in row) for row in r @ np.asarray(params.T1))


def test_library_files_finds_and_explains(tmp_path):
    lib = TapeLibrary(tmp_path / "lib", run_uid="run-a")
    params = _params()
    assert lib.find(params).why_not.startswith("no library at")
    tape = make_tape(AlignmentParameterSheet(reel_id="level-K5-x", params=params))
    path = lib.file(tape)
    assert path.name == "level-K5-x.json" and (tmp_path / "lib" / INDEX).is_file()
    # the run that filed it is not offered its own reel; any other run is
    mine = lib.find(params)
    assert mine.tape is None and "no reel for K = 5" in mine.why_not
    other = TapeLibrary(tmp_path / "lib", run_uid="run-b")
    assert other.find(params).tape.M == tape.M
    # T1 may move by up to a quarter of sigma_theta, g~ by a quarter of sigma_g
    sig = params.sigma_theta
    assert other.find(_params(T1=_turned(params, 0.2 * sig))).tape.M == tape.M
    assert other.find(_params(g_tilde=params.g_tilde + 0.2 * params.sigma_g)).tape.M == tape.M
    far = other.find(_params(T1=_turned(params, 0.3 * sig)))
    assert far.tape is None and "tape parameter T1 differs" in far.why_not
    assert f"by {0.3 * sig / ARCSEC:.1f} arcsec" in far.why_not
    g = other.find(_params(g_tilde=params.g_tilde + 0.3 * params.sigma_g))
    assert g.tape is None and "g_tilde" in g.why_not
    assert "no reel for K = 6" in other.find(_params(K=6)).why_not
    # every other Chart I-8 input to round-off
    eps = other.find(_params(eps_t=1.5))
    assert "no reel for K = 5, Delta t = 1 s, eps_t = 1.5 s" in eps.why_not
    whiter = params.phi_n.model_copy(update={"white": params.phi_n.white * 4})
    assert "phi_n.white" in other.find(_params(phi_n=whiter)).why_not


def test_library_index_is_rebuilt_and_strays_ignored(tmp_path):
    root = tmp_path / "lib"
    params = _params()
    a = make_tape(AlignmentParameterSheet(reel_id="a", params=params))
    b = make_tape(AlignmentParameterSheet(reel_id="b", params=_params(K=6)))
    TapeLibrary(root, "r1").file(a)
    TapeLibrary(root, "r1").file(a)  # filed again: not doubled
    (root / "junk.json").write_text("{not a tape")
    (root / INDEX).write_text("garbage")
    lib = TapeLibrary(root, "r2")
    assert [r.reel_id for r in lib.reels()] == ["a"]
    json.loads((root / INDEX).read_text())  # rewritten whole
    # a reel copied in by hand (not in the index) is found after the rebuild
    (root / "b.json").write_text(b.model_dump_json())
    assert lib.find(_params(K=6)).tape.sheet.reel_id == "b"
    assert sorted(r.reel_id for r in lib.reels()) == ["a", "b"]
    # the reel names who filed it: run r1 is still not offered it after the rebuild
    assert TapeLibrary(root, "r1").find(params).tape is None


# ------------------------------------------------------------------------------------ (b)
def _random_station(seed: int):
    """One unit at a site and noise drawn within their admissible ranges."""
    rng = random.Random(seed)
    over = {"site.latitude_deg": rng.uniform(-60.0, 60.0)}
    for i in range(3):  # the class's 10 micro-g/rt-Hz, from half to twice
        over[f"isu.accels.{i}.noise_micro_g_rt_hz"] = rng.uniform(5.0, 20.0)
    return over, rng


@pytest.fixture(scope="module")
def two_days(tmp_path_factory):
    root = tmp_path_factory.mktemp("tapes")
    over, rng = _random_station(20261123)
    seeds = rng.sample(range(1, 10_000), 2)
    lib = root / "library"
    days = []
    for i, seed in enumerate(seeds):
        st = virtual_station("isu", seed=seed, overrides=over)
        out = root / f"day{i + 1}"
        res = run_day(DayRequest(st.cfg, out, quiet=True, tape_library=lib), QUIET)
        days.append((out, res, st))
    return lib, days


def _steps(run_dir, chart):
    sheet = json.loads((run_dir / "sheets" / f"check_{chart}.json").read_text())
    return {s["number"]: s["reading"] for s in sheet["steps"]}


def test_tape_made_once_is_found_and_used_on_the_next_day(two_days):
    lib, ((d1, res1, _), (d2, res2, _)) = two_days
    i7_1, i7_2 = _steps(d1, "I-7"), _steps(d2, "I-7")
    # day 1: no reel yet; both evaluated (steps 1-5) and filed
    assert i7_1["0/level"]["reel_id"] is None and "5/level" in i7_1
    assert i7_1["5/level"]["library"] == lib.name
    filed = {i7_1[f"5/{m}"]["reel_id"] for m in ("level", "gyrocompass")}
    assert {p.stem for p in lib.glob("*.json")} - {"index"} == filed
    # day 2: both found; Chart I-7 stops at the lookup; nothing new filed
    assert sorted(i7_2) == ["0/gyrocompass", "0/level"]
    assert {i7_2[f"0/{m}"]["reel_id"] for m in ("level", "gyrocompass")} == filed
    assert {p.stem for p in lib.glob("*.json")} - {"index"} == filed
    for m in ("level", "gyrocompass"):
        assert (d2 / "tapes" / f"{i7_2[f'0/{m}']['reel_id']}.json").is_file()  # the record's copy
    # each day's survey gives its own T1: they differ, by less than a quarter of sigma_theta
    for m in ("level", "gyrocompass"):
        assert 0 < i7_2[f"0/{m}"]["t1_offset_arcsec"] <= 15.0
    used = {e["method"] + "/" + e["estimator"]: e for e in res2["alignment"] if "skipped" not in e}
    assert "level/posterior" in used
    for e in used.values():
        assert max(abs(z) for z in e["error_over_sigma"]) < 4, e
    level = json.loads((d2 / "sheets" / "alignment_results_level_posterior.json").read_text())
    assert level["filtering_parameter_id"] == i7_2["0/level"]["reel_id"]


def test_tape_with_another_K_is_refused_naming_K(two_days, tmp_path):
    lib, (_, (d2, _, st)) = two_days
    reel = _steps(d2, "I-7")["0/level"]["reel_id"]
    out = tmp_path / "refused"
    cp = subprocess.run(
        [sys.executable, "-m", "laboratory.cli", "align", "--method", "level", "--estimator",
         "posterior", "--calibration", str(d2), "--tape", str(lib / f"{reel}.json"), "--K",
         "100", "--out", str(out)], capture_output=True, text=True)
    assert cp.returncode == 2, cp.stderr
    assert cp.stderr.count("\n") == 1
    assert "tape parameter K differs from the experiment's: tape 150, experiment 100" in cp.stderr
    assert not out.exists()
    # through the library, another K is another experiment: a new reel is made and filed
    before = {p.name for p in lib.glob("*.json")}
    res = run_align(AlignRequest(st.cfg, tmp_path / "k100", "level", "posterior",
                                 calibration=d2, tape_library=lib, quiet=True, warmup_s=60.0,
                                 plan=command_plan(st.cfg, "level", {"K": 100})), QUIET)
    step0 = _steps(tmp_path / "k100", "I-7")["0/level"]
    assert step0["reel_id"] is None and "no reel for K = 100" in step0["why_not"]
    (new,) = {p.name for p in lib.glob("*.json")} - before
    assert "-K100-" in new
    (e,) = res["alignment"]
    assert e["K"] == 100 and max(abs(z) for z in e["error_over_sigma"]) < 4


# ------------------------------------------------------------------------------------ (c)
@pytest.mark.parametrize("way", ["autocollimators", "quick"])
def test_prior_attitude_ways(two_days, tmp_path, way):
    _, (_, (d2, _, st)) = two_days
    st = virtual_station("isu", seed=st.seed,
                         overrides={**st.overrides, "alignment.quick_K": 12,
                                    "alignment.prior_attitude": way})
    out = tmp_path / way
    res = run_align(AlignRequest(st.cfg, out, "level", "posterior", calibration=d2,
                                 quiet=True, warmup_s=60.0), QUIET)
    (e,) = res["alignment"]
    assert max(abs(z) for z in e["error_over_sigma"]) < 4, e
    aps = json.loads((out / "sheets" / "alignment_parameters_level.json").read_text())
    sheets = {p.stem for p in (out / "sheets").glob("*.json")}
    if way == "autocollimators":
        assert "I-3.1, way 1" in aps["prior_source"] and "check_III-2" in sheets
        mirror = json.loads((out / "sheets" / "alignment_results_mirror.json")
                            .read_text())
        assert np.allclose(aps["params"]["T1"], mirror["t"])
    else:
        assert "I-3.1, way 3" in aps["prior_source"] and "12 x 5 s" in aps["prior_source"]
        quick = json.loads((out / "sheets" / "alignment_results_gyrocompass_average_quick.json")
                           .read_text())
        assert quick["K"] == 12 and np.allclose(aps["params"]["T1"], quick["t"])
        assert "check_III-8-quick" in sheets


def test_command_plan_options_and_refusals():
    st = virtual_station("isu", overrides={"alignment.level_K": 90, "alignment.gyro_K": 60})
    cfg = st.cfg
    assert command_plan(cfg, "level", {}).level_K == 90  # the config's [alignment]
    p = command_plan(cfg, "gyrocompass", {"K": 30, "dt": 4.0, "ieu_period": 0.5,
                                          "known_colatitude": True, "quick_K": 5})
    assert (p.gyro_K, p.gyro_dt_s, p.gyro_period_s, p.level_K) == (30, 4.0, 0.5, 90)
    assert p.known_colatitude and p.quick_K == 5
    p = command_plan(cfg, "level", {"K": 30, "mirror_zenith": True, "sigma_theta_arcsec": 20})
    assert (p.level_K, p.gyro_K, p.mirror_zenith, p.sigma_theta_arcsec) == (30, 60, True, 20)
    for method, given, named in (
            ("mirror", {"K": 10}, "--K: the mirror alignment takes no IEU record"),
            ("level", {"dt": 2.1}, "--dt / --ieu-period: level: Delta t 2.1 s is not a whole"),
            ("level", {"K": 0}, "--K: Input should be greater than or equal to 1"),
            ("level", {"prior_attitude": "moon"}, "--prior-attitude: Input should be"),
            ("gyrocompass", {"ieu_period": 5.0, "dt": 10.0}, "--ieu-period: Input should be")):
        with pytest.raises(ValueError, match=named):
            command_plan(cfg, method, given)
    slow = virtual_station("isu", overrides={"instruments.ieu.max_period_s": 1.0}).cfg
    with pytest.raises(ValueError, match="--ieu-period: 1.5 s is longer than the IEU's "
                                         "instruments.ieu.max_period_s = 1 s"):
        command_plan(slow, "level", {"ieu_period": 1.5, "dt": 3.0})
