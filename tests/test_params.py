"""The parameter objects of issue 14: the ISU lab's Site, the alignments' AlignmentOptions, the
day's and the alignment's requests, and the ESG parameters built on the rotor's spec."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from laboratory.isu.align import AlignRequest
from laboratory.isu.day import DayRequest
from laboratory.isu.spec import site_of
from procedures.isu.alignment.common import site_rates
from procedures.isu.alignment.options import DAY_ESTIMATORS, AlignmentOptions
from procedures.isu.alignment.results_sheet import AlignPlan
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.plan import DayPlan
from procedures.isu.sheets import CalibrationResults
from procedures.isu.site import Site
from sim.esg.rotor import LAB_LATITUDE_DEG, RotorSpec
from sim.esg.world import EsgParams, EsgWorld
from sim.units import EARTH_RATE
from station.config.esg import load_esg_params
from station.config.isu import load_config

EARTH_DEG_HR = 15.041067


# ----------------------------------------------------------------------------- Site
@settings(max_examples=60, deadline=None)
@given(lat=hs.floats(-90.0, 90.0), w=hs.floats(15.0, 15.1), g=hs.floats(9.7, 9.9))
def test_site_splits_the_earth_rate_by_the_colatitude(lat, w, g):
    """omega^E sin(lambda) and cos(lambda) (lambda the colatitude) are the north and vertical
    parts: together the whole rate, at the angle lambda from the vertical."""
    s = Site(latitude_deg=lat, g_local_mps2=g, earth_rate_deg_per_hr=w)
    assert math.hypot(s.omega_sin_lambda, s.omega_cos_lambda) == pytest.approx(w, rel=1e-12)
    colat = math.degrees(math.atan2(s.omega_sin_lambda, s.omega_cos_lambda))
    assert colat == pytest.approx(90.0 - lat, abs=1e-9)
    assert s.omega_sin_lambda >= 0.0  # north: the Earth turns eastward at any latitude
    assert s.g * 9.80665 == pytest.approx(g, rel=1e-15)


def test_site_at_the_equator_and_the_pole():
    eq = Site(0.0, 9.78, EARTH_DEG_HR)
    assert (eq.omega_sin_lambda, eq.omega_cos_lambda) == (EARTH_DEG_HR, 0.0)
    pole = Site(90.0, 9.83, EARTH_DEG_HR)
    assert pole.omega_cos_lambda == EARTH_DEG_HR and abs(pole.omega_sin_lambda) < 1e-15


@pytest.mark.parametrize(("kw", "msg"), [
    ({"latitude_deg": 91.0}, "site.latitude_deg: 91 is not a latitude"),
    ({"latitude_deg": math.nan}, "site.latitude_deg: must be a finite number"),
    ({"g_local_mps2": -9.8}, "site.g_local_mps2: must be positive"),
    ({"earth_rate_deg_per_hr": True}, "site.earth_rate_deg_per_hr: must be a finite number"),
    ({"g_local_mps2": "9.8"}, "site.g_local_mps2: must be a finite number"),
])
def test_a_bad_site_is_refused_naming_the_field(kw, msg):
    good = {"latitude_deg": 42.0, "g_local_mps2": 9.80, "earth_rate_deg_per_hr": EARTH_DEG_HR}
    with pytest.raises(ValueError, match=msg):
        Site(**(good | kw))


def test_site_of_the_config_is_the_configured_site():
    cfg = load_config()
    s = site_of(cfg)
    assert (s.latitude_deg, s.g_local_mps2, s.earth_rate_deg_per_hr) == (
        cfg.site.latitude_deg, cfg.site.g_local_mps2, cfg.site.earth_rate_deg_per_hr)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.latitude_deg = 0.0  # type: ignore[misc]


def test_the_gyrocompass_takes_the_surveys_earth_rate_else_the_sites():
    s = Site(30.0, 9.79, EARTH_DEG_HR)
    assert site_rates(None, s) == (s.omega_sin_lambda, s.omega_cos_lambda)
    with pytest.raises(ValueError, match="needs the Earth rate: give the survey"):
        site_rates(None, None)


# ----------------------------------------------------------------------------- AlignmentOptions
def _options(**kw) -> AlignmentOptions:
    return AlignmentOptions(noise=NoiseSpec(), calib=CalibrationResults(rows=[],
                            positions_used=[]), **kw)


def test_alignment_options_hold_the_canonical_techniques():
    o = _options()
    assert dict(o.estimators) == dict(DAY_ESTIMATORS) and o.plan == AlignPlan()
    assert o.needs_tape() == ("level", "gyrocompass")
    o = _options(estimators={"level": ("hybrid", "posterior", "average"),
                             "gyrocompass": ("posterior",), "mirror": ("hybrid",)})
    # level has no Earth rate (its hybrid is the posterior mean); the gyrocompass's posterior
    # mean is the hybrid (Chart III-10); the mirror alignment averages
    assert o.techniques("level") == ("posterior", "average")
    assert o.techniques("gyrocompass") == ("hybrid",)
    assert o.techniques("mirror") == ("average",)
    assert o.tape_for("level", "average") is None and o.tape_for("level", "posterior") is None
    assert _options(estimators={"level": ("average",)}).needs_tape() == ()


@pytest.mark.parametrize(("kw", "msg"), [
    ({"estimators": {"sextant": ("average",)}}, "estimators: unknown alignment method"),
    ({"estimators": {"level": ("kalman",)}}, "unknown estimator 'kalman'"),
    ({"tapes": {"mirror": None}}, "tapes: no tape for method.s. mirror"),
])
def test_alignment_options_refuse_what_no_chart_runs(kw, msg):
    with pytest.raises(ValueError, match=msg):
        _options(**kw)


def test_alignment_options_are_frozen():
    o = _options()
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.plan = AlignPlan(level_K=10)  # type: ignore[misc]
    with pytest.raises(TypeError):
        o.estimators["level"] = ("average",)  # type: ignore[index]
    with pytest.raises(ValueError, match="frozen"):
        o.plan.level_K = 10  # type: ignore[misc]


# ----------------------------------------------------------------------------- requests
def test_day_request_refuses_unknown_charts_and_positions(tmp_path):
    cfg = load_config()
    with pytest.raises(ValueError, match=r"--only: unknown chart\(s\) II-99"):
        DayRequest(cfg, tmp_path, only=("II-6", "II-99"))
    with pytest.raises(ValueError, match=r"--positions: unknown position\(s\) 0, 16"):
        DayRequest(cfg, tmp_path, positions=(0, 3, 16))
    assert not any(tmp_path.iterdir())  # refused before anything was written


def test_day_request_is_a_value(tmp_path):
    cfg = load_config()
    r = DayRequest(cfg, str(tmp_path), only=["II-11"], positions=[7, 8])  # type: ignore[arg-type]
    assert r.out == Path(tmp_path) and r.only == ("II-11",) and r.positions == (7, 8)
    assert (r.plan, r.align_plan, r.tape_library, r.align, r.resume, r.links) == (
        DayPlan(), None, None, True, False, None)  # None: the config's [alignment]
    assert r == DayRequest(cfg, tmp_path, only=("II-11",), positions=(7, 8))
    assert DayRequest(cfg, tmp_path, positions=()).positions == ()  # no positions, not all
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.resume = True  # type: ignore[misc]


def test_align_request_defaults(tmp_path):
    r = AlignRequest(load_config(), str(tmp_path), "level")  # type: ignore[arg-type]
    assert (r.out, r.estimator, r.calibration, r.tape, r.plan, r.warmup_s) == (
        Path(tmp_path), "average", None, None, None, None)
    assert load_config().alignment.plan() == AlignPlan()  # the embedded [alignment]


# ----------------------------------------------------------------------------- ESG
def test_esg_params_default_to_the_rotor_spec():
    p = EsgParams()
    assert p.rotor == RotorSpec()
    assert p.latitude_deg == LAB_LATITUDE_DEG == RotorSpec().latitude_deg
    assert p.spin_rps == RotorSpec().spin_rps
    w = EsgWorld(1, p)
    assert w.rotor.spec is p.rotor
    lat = math.radians(LAB_LATITUDE_DEG)  # the Earth rate the rotor turns against, in ENU
    assert w.rotor.omega == (0.0, EARTH_RATE * math.cos(lat), EARTH_RATE * math.sin(lat))


def test_esg_config_scalars_reach_the_rotor(tmp_path):
    f = tmp_path / "esg.toml"
    f.write_text("[esg]\nlatitude_deg = 40.0\nspin_rps = 300.0\nunbalance_dyne_cm = 2.0\n")
    p = load_esg_params(f)
    assert p.rotor == dataclasses.replace(RotorSpec(), latitude_deg=40.0, spin_rps=300.0,
                                          unbalance_dyne_cm=2.0)
    w = EsgWorld(1, p)
    assert w.rotor.profile.target == 300.0
    assert w.rotor.unbalance == 2.0 / RotorSpec().inertia_g_cm2
