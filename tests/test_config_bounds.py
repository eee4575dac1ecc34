"""Every magnitude a configuration sets is bounded, the bounds agree with the code they
are derived from, the defaults sit inside them, and the CIGTF latitude limit is where the
gyrocompass test stops telling the truth."""

from __future__ import annotations

import inspect
import math
from dataclasses import replace
from typing import Annotated, Any, Literal, Union, get_args, get_origin

import annotated_types as at
import pytest
from pydantic import BaseModel

import sim.isu.params
import sim.isu.unit
from laboratory.cigtf.gyrocompassing import run_gyrocompass_test
from procedures.cigtf import procedure as gyrocompass_procedure
from procedures.cigtf.scale import gsf_from_turn
from procedures.esg.acquisition import EsgPlan
from procedures.isu.plan import DayPlan
from sim.cigtf.world import CigtfParams
from sim.esg.world import EsgParams
from sim.isu.environment import Environment
from sim.isu.params import DRIFT_KNOT_S, WANDER_KNOT_S
from sim.isu.trajectory import plan_move
from station.config import cigtf as cigtf_config
from station.config.cigtf import CigtfConfig, load_cigtf_params, max_tan_latitude
from station.config.esg import EsgConfig, PatternConfig, SignalConfig
from station.config.file import LABORATORIES
from station.config.isu import ConfigError, StationConfig, default_dict, load_config
from station.drivers.isu.table import TableDriver

MODELS = (StationConfig, CigtfConfig, EsgConfig)


def numbers(model: type[BaseModel], at_: str = "") -> list[tuple[str, Any, list]]:
    """(path, type, constraints) of every number a model holds, through nested models,
    tuples, dicts and Optionals."""
    out: list[tuple[str, Any, list]] = []

    def walk(tp: Any, where: str, meta: list) -> None:
        origin = get_origin(tp)
        if origin is Annotated:
            base, *extra = get_args(tp)
            more = [m for x in extra for m in getattr(x, "metadata", [x])]
            walk(base, where, meta + more)
        elif origin is Union or type(tp).__name__ == "UnionType":
            for a in get_args(tp):
                if a is not type(None):
                    walk(a, where, meta)
        elif origin in (tuple, list):
            for i, a in enumerate(get_args(tp)):
                if a is not Ellipsis:  # tuple[X, ...]: X once
                    walk(a, f"{where}.{i}", meta)
        elif origin is dict:
            walk(get_args(tp)[1], f"{where}.*", meta)
        elif isinstance(tp, type) and issubclass(tp, BaseModel):
            out.extend(numbers(tp, where))
        elif tp in (int, float):
            out.append((where, tp, meta))
        elif tp is str or origin is Literal or tp is bool:
            pass
        else:
            raise AssertionError(f"{where}: unexpected type {tp}")

    for name, f in model.model_fields.items():
        walk(f.annotation, f"{at_}.{name}".lstrip("."), list(f.metadata))
    return out


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.__name__)
def test_every_magnitude_has_a_lower_and_an_upper_bound(model):
    unbounded = []
    for where, _, meta in numbers(model):
        lower = any(isinstance(m, at.Ge | at.Gt) for m in meta)
        upper = any(isinstance(m, at.Le | at.Lt) for m in meta)
        if not (lower and upper):
            unbounded.append(where)
    # links.can's extra options are python-can's business (checked scalar and finite)
    assert unbounded == [], unbounded


def test_the_default_configurations_are_inside_their_bounds():
    load_config()
    p = CigtfParams()
    CigtfConfig.model_validate({k: getattr(p, k) for k in CigtfConfig.model_fields
                                 if k not in ("limits", "eq27")})  # not the fixture's
    e = EsgParams()
    EsgConfig.model_validate(
        {**{k: getattr(e.rotor, k) for k in EsgConfig.model_fields
            if k not in ("pattern", "signal", "limits", "reduction", "procedure")},
         "pattern": {k: getattr(e.pattern, k) for k in PatternConfig.model_fields},
         "signal": {k: getattr(e.signal, k) for k in SignalConfig.model_fields}})


def test_top_level_names_are_the_models_fields():
    assert set(LABORATORIES["ISU"]) == set(StationConfig.model_fields)


def test_knot_steps_agree_with_the_simulation():
    """The time-constant bounds (ten knots per tau) use the knot steps of sim.isu.environment
    and sim.isu.unit."""
    assert WANDER_KNOT_S == Environment.WANDER_KNOT
    assert DRIFT_KNOT_S == sim.isu.unit.DRIFT_KNOT


def test_table_and_gyro_bounds_agree_with_the_day():
    """The table must turn at the day's top rate and ramp as II-10 does, settle a half
    turn within the driver's wait, and the gyros must not saturate at that rate."""
    plan = DayPlan()
    top = max(plan.table_rate_deg_s, plan.j_rate_deg_s,
              *(abs(r) for r in plan.nonlinearity_rates_deg_s))
    assert top <= sim.isu.params.TOP_RATE_DEG_S
    assert plan.j_accel_deg_s2 <= sim.isu.params.RAMP_DEG_S2
    wait = inspect.signature(TableDriver.wait_still).parameters["timeout"].default
    assert wait == sim.isu.params.MOVE_WAIT_S
    _, t_done = plan_move(0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 2.0)
    assert t_done == pytest.approx(sim.isu.params.SETTLE_TAUS * 2.0)
    cfg = load_config()
    for g in cfg.isu.gyros:
        assert g.pulse_rate_hz * g.scale_factor_arcsec_per_pulse >= sim.isu.params.MIN_RANGE_DEG_HR


def test_a_table_that_cannot_settle_in_time_is_refused():
    with pytest.raises(ConfigError, match=r"table\.settle_tau_s: with slew_rate_deg_s = 2\.0 "
                       r"and slew_accel_deg_s2 = 1\.0, a 180 deg move would take 158 s"):
        load_config(overrides={"table": {"slew_rate_deg_s": 2.0, "slew_accel_deg_s2": 1.0,
                                         "settle_tau_s": 10.0}})
    with pytest.raises(ConfigError, match=r"table\.max_rate_deg_s: Input should be greater "
                       r"than or equal to 15"):
        load_config(overrides={"table": {"max_rate_deg_s": 12.0}})


def test_a_gyro_that_saturates_at_the_top_rate_is_refused():
    gyros = default_dict()["isu"]["gyros"]
    gyros[2]["pulse_rate_hz"] = 15000.0  # 45000 deg/hr: under 15 deg/s
    with pytest.raises(ConfigError, match=r"isu\.gyros\.2\.pulse_rate_hz: with "
                       r"scale_factor_arcsec_per_pulse = 3\.0031 the rebalance range is "
                       r"4\.505e\+04 deg/hr"):
        load_config(overrides={"isu": {"gyros": gyros}})


def test_cigtf_figures_agree_with_the_test_plan():
    plan = gyrocompass_procedure.TestPlan()
    assert cigtf_config.SAMPLES == plan.samples
    assert cigtf_config.OPERATING_RUNS == plan.operating_runs
    assert inspect.signature(gsf_from_turn).parameters["turn_deg"].default == cigtf_config.TURN_DEG


def test_esg_rotor_bounds_agree_with_the_plan():
    plan = EsgPlan(latitude_deg=EsgParams().latitude_deg)

    def bound(model, field, kind):
        return next(getattr(m, kind) for m in model.model_fields[field].metadata
                    if hasattr(m, kind))

    assert bound(EsgConfig, "spin_rps", "ge") >= plan.spin_ready_rps
    assert bound(EsgConfig, "damping_tau_s", "le") <= plan.damping_s / 3


def test_the_cigtf_latitude_limit_is_derived():
    """tan(limit) = sin(1 deg) / (2 sqrt(2 N) b), b = 3 level sd in rad: 87.98 deg for the
    default 3 arcsec, 90 deg without a level error, and symmetric."""
    assert math.degrees(math.atan(max_tan_latitude(3.0))) == pytest.approx(87.975, abs=1e-3)
    assert max_tan_latitude(0.0) == math.inf
    assert math.degrees(math.atan(max_tan_latitude(1.0))) == pytest.approx(89.325, abs=1e-3)


def test_cigtf_latitude_accepted_up_to_the_limit(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text("[cigtf]\nlatitude_deg = -87.9\n")
    assert load_cigtf_params(f).latitude_deg == -87.9
    f.write_text("[cigtf]\nlatitude_deg = 88.0\n")
    with pytest.raises(ConfigError, match=r"cigtf\.latitude_deg: 88 deg is too near the pole"):
        load_cigtf_params(f)
    f.write_text("[cigtf]\nlevel_sd_arcsec = 1.0\nlatitude_deg = 88.0\n")
    assert load_cigtf_params(f).latitude_deg == 88.0  # a better-levelled fixture goes further


def _z(lat: float, seed: int, tmp_path) -> float:
    """The operating phase's theta minus the truth (eq. 26), in its own sigmas."""
    res = run_gyrocompass_test(seed, tmp_path / f"{lat}-{seed}",
                               params=replace(CigtfParams(), latitude_deg=lat,
                                              pretest_setup=False))  # b at level_sd_arcsec
    op = next(p for p in res["phases"] if p["phase"] == "operating")
    return (op["theta_arcsec"] - res["truth"]["theta_arcsec"]) / op["sigma_arcsec"]


def test_the_limit_separates_honest_results_from_misleading_ones(tmp_path):
    """Just inside the limit the operating phase's theta sits within 3 sigma of the truth;
    near the pole (where the configuration refuses it) a run reports a theta 6 sigma off
    the truth: the test would mislead rather than fail."""
    assert all(abs(_z(87.9, seed, tmp_path)) < 3.0 for seed in (1, 2))
    assert abs(_z(89.9, 2, tmp_path)) > 5.0


def _esg_file(tmp_path, pattern: dict) -> str:
    lines = "".join(f"{k} = {v!r}\n".replace("'", '"') for k, v in pattern.items())
    f = tmp_path / "esg.toml"
    f.write_text("[esg.pattern]\n" + lines)
    return str(f)


def test_esg_patterns_the_calibration_cannot_use_are_refused_naming_the_field(tmp_path):
    """Lines ending too near the equal-ratio colatitude (steps 4, 6), or a great circle too
    flat to reach its lines' end (ESG-DPX found no pattern there), are refused at loading;
    the limits themselves are accepted."""
    from station.config.esg import load_esg_params

    with pytest.raises(ConfigError, match=r"esg\.pattern\.top_colatitude_deg: lines that end "
                       r"at colatitude 54 deg .* at most 53\.7 on a great circle"):
        load_esg_params(_esg_file(tmp_path, {"top_colatitude_deg": 54.0}))
    with pytest.raises(ConfigError, match=r"esg\.pattern\.top_colatitude_deg: .* at most 51 "
                       r"on a cosine"):
        load_esg_params(_esg_file(tmp_path, {"kind": "cosine", "top_colatitude_deg": 52.0}))
    with pytest.raises(ConfigError, match=r"esg\.pattern: inclination_deg = 53 with "
                       r"top_colatitude_deg = 43: .* at least 53\.33 deg"):
        load_esg_params(_esg_file(tmp_path, {"inclination_deg": 53.0}))
    # the default inclination with lines that end higher up: the same check
    with pytest.raises(ConfigError, match=r"inclination_deg = 56 with top_colatitude_deg = 36"):
        load_esg_params(_esg_file(tmp_path, {"top_colatitude_deg": 36.0}))
    # a wider set-up offset needs more inclination (3 sd of it at the logic line's edge)
    with pytest.raises(ConfigError, match=r"at least 54\.97 deg"):
        load_esg_params(_esg_file(tmp_path, {"inclination_deg": 54.9, "d0_sd_in": 0.01}))
    assert load_esg_params(_esg_file(tmp_path, {"top_colatitude_deg": 53.7})).pattern \
        .top_colatitude_deg == 53.7
    assert load_esg_params(_esg_file(tmp_path, {"kind": "cosine", "top_colatitude_deg": 30.0,
                                                "inclination_deg": 20.0})).pattern.kind == "cosine"
    assert load_esg_params(_esg_file(tmp_path, {"inclination_deg": 53.34})).pattern \
        .inclination_deg == 53.34


def test_esg_pattern_limits_agree_with_the_procedure():
    """The loader's equal-ratio colatitude is the procedure's for the measured mirror angle,
    and the extremity margin is one of sheet ESG-DPX's tries."""
    from procedures.esg.acquisition import MIRROR_ANGLE_DEG
    from procedures.esg.mechanization import equal_ratio_colatitude, pickoff_gram
    from procedures.esg.setup import EXTREMITY_STEPS_DEG
    from station.config import esg

    theta = equal_ratio_colatitude(pickoff_gram(MIRROR_ANGLE_DEG))
    assert esg.EQUAL_RATIO_COLATITUDE_DEG == pytest.approx(theta, abs=0.005)
    assert esg.TOP_LIMIT_DEG["great_circle"] <= theta - 1.0
    assert esg.EXTREMITY_MARGIN_DEG in EXTREMITY_STEPS_DEG
