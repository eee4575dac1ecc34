"""Mirror and pickoff alignment as adjustments (report 004, "Mirror and Pickoff Alignment",
procedure step 1; issue 20), pickoff 2 aligned with the case remounted (sheet ESG-PA2),
pickoff 3's tilt towards mirror 1 removed after step 3, and the strategy variants and
Figure 3 in the run's record (report 004, "Pattern Analysis", Figure 3). One calibration
serves all: a case mounted beyond the 3 arcsec coning limit with pickoffs 1, 2 and 3
beyond 15 arcsec, adjusted, with the variants computed at 1000 orientations."""

from __future__ import annotations

import json
import math
import tomllib

import pytest
from typer.testing import CliRunner

from laboratory.cli import app
from laboratory.esg.calibration import procedure_record, run_esg_calibration
from laboratory.esg.truth import (
    true_pickoff1_coning_arcsec,
    true_pickoff3_spindle_tilt_arcsec,
    true_pickoff3_tilts_arcsec,
    true_pickoff_coning_arcsec,
    true_pickoff_mirror_arcsec,
)
from laboratory.esg.variants import FIGURE3_RANGES
from procedures.esg import strategy_variants as sv
from procedures.esg.acquisition import EsgPlan
from procedures.runner import ProcedureError
from sim.units import ARCSEC
from station.config.esg import load_esg_procedure
from station.errors import InstrumentRefused
from station.racks.esg import EsgRack, open_esg_drivers

GOAL = 15.0
POINTS = 1000


def _misalign(rack: EsgRack) -> None:
    """Mirror 1 about 17 arcsec off the spindle, pickoff 1 about 40 arcsec off it,
    pickoff 2 about 50 arcsec off mirror 2, pickoff 3 about 37 arcsec off its nominal
    line (towards mirror 1)."""
    rack.world.shim(15.0, -10.0)
    rack.world.translate_pickoff(1, 40.0, -30.0)
    rack.world.translate_pickoff(2, 40.0, -30.0)
    rack.world.translate_pickoff(3, 40.0, 0.0)


def _steps(out) -> dict[str, dict]:
    steps = {}
    for line in (out / "journal.jsonl").read_text().splitlines():
        r = json.loads(line)
        if r.get("kind") == "step":
            steps[r["step"]] = r["reading"]
    return steps


@pytest.fixture(scope="module")
def adjusted(tmp_path_factory):
    out = tmp_path_factory.mktemp("esg_adjusted")
    racks: list[EsgRack] = []

    def hook(rack: EsgRack) -> None:
        racks.append(rack)
        _misalign(rack)

    plan = EsgPlan(latitude_deg=0.0, adjust_alignment=True, remount_alignment=True)
    res = run_esg_calibration(1, out, plan=plan, rack_hook=hook, with_study=False,
                              variants_points=POINTS)
    return out, res, racks[0].world


def test_mount_shimmed_within_3_arcsec_of_the_spindle(adjusted):
    out, res, world = adjusted
    st = _steps(out)
    assert st["1"]["coning_radius_arcsec"] > 3.0  # the check would have stopped here
    shims = [k for k in st if k.startswith("1.shim-")]
    assert shims and all(len(st[k]["shim_arcsec"]) == 2 for k in shims)
    true = world.case.coning_rad / ARCSEC
    assert true <= 3.0
    measured = st[shims[-1]]["coning_radius_arcsec"]
    assert measured == res["acquisition"]["mount_coning_arcsec"] <= 3.0
    # eight theodolite readings of 0.5 arcsec rms: the radius to 0.25 arcsec (1 sigma)
    assert abs(measured - true) < 4 * 0.25


def test_pickoff_translated_within_15_arcsec_of_the_spindle(adjusted):
    out, res, world = adjusted
    st = _steps(out)
    assert st["PA.1"]["coning_arcsec"] - 3 * st["PA.1"]["sigma_arcsec"] > 15.0
    moves = [k for k in st if k.startswith("PA.translate-")]
    assert moves and "PA.tilt" in st
    last = st[moves[-1]]
    true = true_pickoff1_coning_arcsec(world)
    assert true <= 15.0 and last["coning_arcsec"] <= 15.0
    assert abs(last["coning_arcsec"] - true) < 3 * last["sigma_arcsec"]
    assert res["acquisition"]["true_pickoff_coning_arcsec"] == pytest.approx(true)


def test_pickoff2_aligned_with_the_case_remounted(adjusted):
    """ESG-PA2: mirror 2 shimmed onto the spindle, pickoff 2 translated from beyond 15
    arcsec to within it (measured within 3 sigma of the simulator's coning), the case
    mounted back with mirror 1 along the spindle."""
    out, _, world = adjusted
    st = _steps(out)
    assert true_pickoff_mirror_arcsec(world, 2, 0.0) > 15.0  # off mirror 2 at the start
    assert st["PA2.mount"]["coning_radius_arcsec"] > 3.0
    shims = [k for k in st if k.startswith("PA2.shim-")]
    assert shims and st[shims[-1]]["coning_radius_arcsec"] <= 3.0
    assert st["PA2.1"]["coning_arcsec"] - 3 * st["PA2.1"]["sigma_arcsec"] > 15.0
    moves = [k for k in st if k.startswith("PA2.translate-")]
    assert moves
    last = st[moves[-1]]
    true_then = true_pickoff_coning_arcsec(world, 2, last["t_s"][-1])
    assert true_then <= 15.0 and last["coning_arcsec"] <= 15.0
    assert abs(last["coning_arcsec"] - true_then) < 3 * last["sigma_arcsec"]
    assert true_pickoff_mirror_arcsec(world, 2) <= 15.0  # against its mirror, now
    assert st["PA2.remount"]["spin_rps"] == 0.0 and world.case.mirror_on_spindle == 1


def test_pickoff3_tilt_towards_mirror_1_translated_out(adjusted):
    """Pickoff 3 beyond 15 arcsec off m1 x m2 at the start is within 15 after its tilt
    towards mirror 1 is measured (within 3 sigma of the simulator's tilt towards the
    spindle at that time, every measurement) and translated out along c1."""
    out, _, world = adjusted
    st = _steps(out)
    assert true_pickoff3_tilts_arcsec(world, 0.0)[2] > GOAL
    done = [k for k in st if k == "3.p3-1" or k.startswith("3.p3-translate-")]
    assert len(done) >= 2 and abs(st["3.p3-1"]["tilt_arcsec"]) > GOAL
    for k in done:
        m = st[k]
        true = true_pickoff3_spindle_tilt_arcsec(world, m["along"]["t_s"][-1])
        assert abs(m["tilt_arcsec"] - true) < 3 * m["sigma_arcsec"]
    assert st[done[-1]]["translation_arcsec"][1] == 0.0  # along c1 only
    assert true_pickoff3_tilts_arcsec(world)[2] <= GOAL


def test_readout_after_the_adjustment_is_within_its_sigma_of_truth(adjusted):
    _, res, _ = adjusted
    for s in res["schedules"]:
        assert s["true_readout_rms_arcsec"] < GOAL
        both = math.hypot(s["readout_rms_arcsec"], 2.5 * s["predicted_assignment_rms_arcsec"])
        assert s["true_readout_rms_arcsec"] < both


def test_without_the_adjustment_the_check_stops_the_run(tmp_path):
    with pytest.raises(ProcedureError, match="mirror coning .* exceeds 3: re-shim"):
        run_esg_calibration(1, tmp_path, rack_hook=_misalign, with_study=False)


def test_shim_refused_with_the_rotor_spinning():
    rack = EsgRack(1)
    st = open_esg_drivers(rack)
    st.console.spin_up()
    st.clock.sleep(10.0)
    with pytest.raises(InstrumentRefused) as e:
        st.head.shim(1.0, 1.0)
    assert e.value.code == 19 and "rotor spinning" in e.value.text
    with pytest.raises(InstrumentRefused) as e:
        st.head.mount(2)
    assert e.value.code == 19 and "remount the case at rest" in e.value.text


def test_variants_in_the_record_are_the_study_s(adjusted):
    """esg.json and the sheets hold what strategy_variants gives at the same settings."""
    out, _, _ = adjusted
    got = json.loads((out / "esg.json").read_text())["strategy_variants"]
    assert got["points"] == POINTS and got["range_deg"] == 43.0
    assert got["table"] == sv.variants_table(43.0, POINTS)
    assert got["figure3"] == [sv.figure3(float(r), POINTS) for r in FIGURE3_RANGES]
    sheet = json.loads((out / "sheets" / "esg_strategy_variants.json").read_text())
    assert sheet == got["table"]
    assert (out / "esg_figure3.png").stat().st_size > 0


def test_figure3_all_three_below_the_two_pickoff_minimum(adjusted):
    """Figure 3: using all three pickoffs (eq. 3) is never worse than the best pair, so
    its RMS curve lies under the two-pickoff minimum and under the mixed curve."""
    out, _, _ = adjusted
    curves = json.loads((out / "esg.json").read_text())["strategy_variants"]["figure3"]
    for c in curves:
        assert c["all_three"] <= c["two_min"] and c["all_three"] <= c["mixed"]


def test_procedure_settings_in_the_record_s_config(adjusted):
    out, _, _ = adjusted
    doc = tomllib.loads((out / "config.toml").read_text())
    assert doc["esg"]["procedure"] == {"strategy_variants": True, "adjust_alignment": True,
                                       "remount_alignment": True,
                                       "strategy_variants_points": POINTS}
    proc = load_esg_procedure(out / "config.toml")  # what a re-analysis reads back
    assert (proc.strategy_variants, proc.adjust_alignment, proc.strategy_variants_points,
            proc.counters, proc.extremity_setup, proc.remount_alignment) == (
                True, True, POINTS, 2, True, True)
    assert procedure_record(EsgPlan(latitude_deg=0.0), None) == {}  # a default run's


def test_bad_procedure_settings_name_the_field(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text("[esg.procedure]\nstrategy_variants_points = 10\n")
    r = CliRunner().invoke(app, ["esg-calibration", "--out", str(tmp_path / "a"),
                                 "--config", str(cfg)])
    assert r.exit_code == 2 and "esg.procedure.strategy_variants_points" in r.output
