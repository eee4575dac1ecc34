"""The three-counter data processor (report 004, section "Line edge error estimation": its
two interval counters timed two pickoffs at once, so the third was left unused even where
it saw the pattern): the option that reads all three pickoffs in one revolution, the
three-pickoff attitude readout from the acquired lines, and the calibration run with it
(docs/esg-options.md)."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from laboratory.esg.calibration import run_esg_calibration
from procedures.esg.readings import read_setting
from procedures.esg.readout import spin_axis_three, variance_three
from sim.esg import EsgParams
from station.config.esg import EsgConfig, params_from
from station.errors import InstrumentRefused
from station.racks.esg import EsgRack, open_esg_drivers

ARCSEC = math.pi / 180.0 / 3600.0


def _spinning(params: EsgParams, seed: int):
    rack = EsgRack(seed, params)
    st = open_esg_drivers(rack)
    st.console.spin_up()
    st.clock.sleep(rack.world.p.rotor.spinup_s + 60.0)
    return rack, st


def test_a_two_counter_processor_refuses_a_third_pickoff():
    rack, st = _spinning(EsgParams(), 5)
    with rack:
        with pytest.raises(InstrumentRefused, match=r"usage: SEL <a> <b>$"):
            st.processor.select(1, 2, 3)
        assert st.processor.settings()["pickoffs"] == (2, 3)
        st.close()


def test_config_sets_the_counters():
    cfg = EsgConfig.model_validate({"procedure": {"counters": 3}})
    assert params_from(cfg).counters == 3
    assert params_from(EsgConfig.model_validate({})).counters == 2
    with pytest.raises(ValueError, match="counters"):
        EsgConfig.model_validate({"procedure": {"counters": 4}})


@pytest.mark.parametrize("seed", [3, 8])
def test_three_pickoffs_in_one_setting_read_the_true_attitude(seed):
    """At the equal-ratio direction every pickoff views the pattern: one setting gives the
    three count ratios (each the simulator's noise-free ratio within 5 sigma of the line
    scatter) and the normalised three-pickoff readout (eq. 3) the simulator's spin axis
    in the case within 5 predicted sigma."""
    rack, st = _spinning(replace(EsgParams(), counters=3), seed)
    with rack:
        w = rack.world
        p = w.case.pickoffs
        d = np.linalg.solve(p, np.ones(3))
        w.place_spin_axis(w.case_to_lab(w.now) @ (d / np.linalg.norm(d)))
        s = read_setting(st.processor, (1, 2, 3), 5)
        assert st.processor.settings()["pickoffs"] == (1, 2, 3)
        assert all(s.cr[k] is not None for k in (1, 2, 3))
        # the simulator's own pattern, inverted on a fine grid (the pattern is the rotor's)
        th = np.radians(np.linspace(45.0, 65.0, 40001))
        cr_grid = w.pattern.count_ratio(th)
        order = np.argsort(cr_grid)
        theta, var = [], []
        for k in (1, 2, 3):
            lines = np.array(s.line_cr[k])
            sigma = max(float(np.std(lines, ddof=1)), 3e-6) / math.sqrt(len(lines))
            truth = w.true_count_ratio(k, s.t_s)
            assert abs(s.ratio(k) - truth) < 5.0 * sigma + 2e-6, k
            t_k = float(np.interp(s.ratio(k), cr_grid[order], th[order]))
            slope = abs(float(np.gradient(cr_grid, th)[np.searchsorted(th, t_k)]))
            theta.append(t_k)
            var.append((math.sin(t_k) * sigma / slope) ** 2)  # of the cosine
        s_read = spin_axis_three(np.cos(theta), p)
        s_true = w.spin_axis_case(s.t_s)
        err = math.acos(min(1.0, float(s_read @ s_true)))
        # eq. 3 with the cosines' variances (pickoffs orthogonal within arcminutes)
        bound = 5.0 * math.sqrt(float(variance_three(np.cos(theta), var))) + 1.0 * ARCSEC
        assert err < bound, (err / ARCSEC, bound / ARCSEC)
        st.close()


def test_calibration_with_three_counters(tmp_path):
    """The whole calibration on a three-counter processor: step 4 reads the three ratios
    in one setting, every scan point carries pickoff 3 as well, the readout meets the goal
    against the simulator's colatitudes."""
    res = run_esg_calibration(2, tmp_path, params=replace(EsgParams(), counters=3),
                              with_study=False)
    steps = {}
    scan_sel = set()
    for line in (tmp_path / "journal.jsonl").read_text().splitlines():
        j = json.loads(line)
        if j.get("kind") == "note" and j.get("event") == "start":
            assert j["counters"] == 3
        if j.get("kind") != "step":
            continue
        steps[j["step"]] = j
        if j["step"].startswith(("10+.", "11-.")) and "pickoffs" in j["reading"]:
            scan_sel.add(tuple(j["reading"]["pickoffs"]))
    assert scan_sel == {(2, 1, 3)}
    for k in ("4a", "4b"):
        cr = steps[k]["reading"]["count_ratios"]
        assert max(cr.values()) - min(cr.values()) <= 3e-5
    for sched in res["schedules"]:
        assert sched["true_readout_rms_arcsec"] < sched["limit"]
