"""Chart II-6 step 13's option: phi3 turned with the table still moving (issue 20).

The pair's second gate is whole turns after the table is back at its rate, so the scale
factor rows stay within 4 predicted sigma of the simulator's truth; the day is shorter by the
stops and restarts it saves.
"""

from __future__ import annotations

import json

import pytest
from rich.console import Console

from laboratory.isu.day import DayRequest, run_day
from station.config.isu import load_config

QUIET = Console(quiet=True)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    out = {}
    for name, moving in (("stopped", False), ("moving", True)):
        cfg = load_config(seed=11, overrides={"calibration": {"turn_phi3_moving": moving}})
        d = tmp_path_factory.mktemp(name)
        out[name] = (d, run_day(DayRequest(cfg, d, only=("II-6",), quiet=True, align=False),
                                QUIET))
    return out


def test_scale_factor_rows_within_4_sigma_with_the_table_moving(pair):
    _, res = pair["moving"]
    rows = [r for r in res["calibration"] if r["estimate"] is not None]
    assert {r["parameter"] for r in rows} >= {"DeltaPhi", "G.B1", "G.B2", "G.B3"}
    for r in rows:
        assert r["sigma"] > 0 and abs(r["error"]) < 4 * r["sigma"], r


def test_the_table_keeps_turning_between_the_pair(pair):
    d, res = pair["moving"]
    steps = {(s.get("chart"), s.get("step")): s for s in
             map(json.loads, (d / "journal.jsonl").read_text().splitlines())}
    for m in (1, 3, 5):
        assert steps[("II-6", f"10/m{m}")]["text"].endswith("the table kept turning")
        assert steps[("II-6", f"12/m{m + 1}")]["text"].endswith("(the table still turning)")
        assert steps[("II-6", f"10/m{m + 1}")]["text"].endswith("stop the table")
    assert res["sim_seconds"] < pair["stopped"][1]["sim_seconds"]
