"""`station campaign` with ``[laboratory] random = true`` (issue 19, docs/campaigns.md): each
task's random laboratory is its own (drawn from the task's SeedSequence, whatever the number
of tasks), its draws are the task's ``lab.*`` columns, the station a task runs is that
laboratory with a reachable ``[plan]``, a spec without ``[laboratory]`` keeps its digest, and
a random laboratory outside the isu commands is refused naming the field."""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import pandas as pd
import pytest

from laboratory.campaign.spec import LAB_COLUMNS, CampaignSpec, SpecError, load_spec, tasks
from laboratory.campaign.summary import summarise
from laboratory.campaign.task import random_station
from laboratory.isu.random_lab import DRIFT_PER_DAY, FREQUENCY_ERROR


def _spec(**kw: object) -> CampaignSpec:
    return CampaignSpec.model_validate({"command": "day", "seeds": 4, "seed": 19,
                                        "laboratory": {"random": True}, **kw})


def test_each_task_draws_its_own_laboratory() -> None:
    a = tasks(_spec())
    lats = [t.values["lab.latitude_deg"] for t in a]
    assert len(set(lats)) == 4 and all(5.0 <= abs(x) <= 70.0 for x in lats)
    assert all(0.3 <= t.values[c] <= 3.0 for t in a for c in LAB_COLUMNS[2:5] + LAB_COLUMNS[7:])
    for c, (lo, hi) in zip(LAB_COLUMNS[5:7], (FREQUENCY_ERROR, DRIFT_PER_DAY), strict=True):
        assert all(lo <= abs(t.values[c]) <= hi for t in a), c
    assert [t.values for t in tasks(_spec(seeds=6))][:4] == [t.values for t in a]
    assert _spec().sweep_paths() == list(LAB_COLUMNS)
    # the [random] draws (child 0) and the laboratory (child 1) are separate streams
    r = tasks(_spec(random={"plan.table_rate_deg_s": [9.0, 11.0]}))
    assert [t.values["lab.latitude_deg"] for t in r] == lats


def test_the_tasks_station_is_its_drawn_laboratory() -> None:
    t = tasks(_spec())[1]
    st = random_station(_spec(), t, {})
    cfg = st.cfg
    assert cfg.seed == t.seed
    assert cfg.site.latitude_deg == t.values["lab.latitude_deg"]
    assert math.isclose(cfg.environment.wobble.amplitude_arcsec, t.values["lab.pier_noise"])
    assert cfg.oscillator.frequency_error == t.values["lab.frequency_error"]
    assert cfg.oscillator.drift_per_day == t.values["lab.drift_per_day"]
    assert math.isclose(cfg.table.setting_noise_arcsec, 0.3 * t.values["lab.table_noise"])
    assert math.isclose(cfg.instruments.bubble_level.noise_arcsec,
                        0.2 * t.values["lab.reading_noise"])
    assert math.isclose(cfg.environment.vibration.rms_micro_g,
                        100.0 * t.values["lab.vibration_noise"])
    assert all(v >= d for v, d in zip(cfg.plan.requirements().values(),
                                      (1e-4, 0.02, 2.0, 6.0), strict=True))
    over = random_station(_spec(), t, {"site.latitude_deg": 30.0}).cfg
    assert over.site.latitude_deg == 30.0  # a grid path over the drawn laboratory


def test_spec_without_laboratory_keeps_its_digest_and_bad_use_is_refused(
        tmp_path: Path) -> None:
    plain = CampaignSpec.model_validate({"command": "day", "seeds": 2})
    old = plain.model_dump(mode="json")
    del old["laboratory"]  # the spec as it was before [laboratory]: the same digest
    assert plain.document() == old
    assert plain.digest() == hashlib.sha256(json.dumps(old, sort_keys=True).encode()
                                            ).hexdigest()[:16]
    f = tmp_path / "s.toml"
    f.write_text('command = "gyrocompass-test"\n[laboratory]\nrandom = true\n')
    with pytest.raises(SpecError, match=r"s\.toml: .*laboratory\.random: .*isu laboratory"):
        load_spec(f)
    f.write_text('command = "day"\n[laboratory]\nrandom = true\nnoise = -1.0\n')
    with pytest.raises(SpecError, match=r"s\.toml: laboratory\.noise: "):
        load_spec(f)


def test_summary_gives_each_estimators_ratio() -> None:
    rows = pd.DataFrame([{"instrument": "accel1", "parameter": "D0", "units": "g",
                          "error": e, "sigma": 1.0, "z": e, "z_closed_form": 2 * e,
                          "z_all_positions": e} for e in (1.0, -1.0, 1.0, -1.0)])
    s = summarise(rows, []).iloc[0]
    assert (s["ratio"], s["ratio_closed_form"], s["ratio_all_positions"]) == (1.0, 2.0, 1.0)
    assert s["n_closed_form"] == 4 and s["max_abs_z_closed_form"] == 2.0
