"""Standard exports (issue 15): results.csv row for row with results.json, the raw IEU
samples of an alignment as CSV, and the run's CAN log read back with python-can and
decoded with the DBC into the very samples the sampling step used."""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path

import can
import pytest
from rich.console import Console

from config.dbc import load_dbc
from laboratory.export import CAN_LOG, can_log, csv_cell, write_alignment_samples
from laboratory.isu.day import DayRequest, run_day
from procedures.isu.alignment.sampling import RAW_COLUMNS, collect
from station.config.isu import load_config
from station.drivers.isu.ieu import COUNT_PARTS
from station.racks.isu import SimulatedRack, open_isu_drivers

QUIET = Console(quiet=True)


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def day(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("exports") / "day"
    res = run_day(DayRequest(load_config(seed=11), out, only=("II-11",), positions=(7,),
                             quiet=True), QUIET)
    return out, res


def test_results_csv_equals_results_json_row_for_row(day: tuple[Path, dict]) -> None:
    out, _ = day
    rows = json.loads((out / "results.json").read_text())["calibration"]
    got = read_csv(out / "results.csv")
    assert len(got) == len(rows) > 0
    for r, c in zip(rows, got, strict=True):
        assert set(c) == set(r)  # the same keys, as columns
        assert c == {k: csv_cell(v) for k, v in r.items()}
        for k, v in r.items():  # and the numbers read back exactly
            if isinstance(v, float):
                assert float(c[k]) == v
    aligned = json.loads((out / "results.json").read_text())["alignment"]
    assert len(read_csv(out / "alignment.csv")) == len(aligned)


def test_day_logs_its_ieu_frames(day: tuple[Path, dict]) -> None:
    out, res = day
    msgs = list(can.LogReader(out / CAN_LOG))
    db = load_dbc()
    names = [db.get_message_by_frame_id(m.arbitration_id).name for m in msgs]
    assert "IEU_COMMAND" in names and "IEU_STATUS" in names
    assert all(not m.is_rx for m, n in zip(msgs, names, strict=True) if n == "IEU_COMMAND")
    assert all(m.is_rx for m, n in zip(msgs, names, strict=True) if n != "IEU_COMMAND")
    times = [m.timestamp for m in msgs]
    assert times == sorted(times) and 0.0 <= times[0] and times[-1] <= res["sim_seconds"]


@dataclass
class _Outcome:
    method: str
    estimator: str
    detail: dict = field(default_factory=dict)


def test_can_log_decodes_into_the_samples_the_run_used(tmp_path: Path) -> None:
    cfg = load_config(seed=5)
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    try:
        with can_log(tmp_path, st.ieu):
            rec = collect(st, 1000, 4, 6, s2=1e-3)
    finally:
        st.close()
        rack.close()
    assert rec.raw is not None
    used = rec.raw.rows()
    assert len(used) == 24
    # the raw samples sum to the record the alignment uses
    assert [sum(u["A1S1"] for u in used[i * 4:(i + 1) * 4]) for i in range(6)] == \
        rec.strings[:, 0].tolist()

    # the CSV of the raw samples, as the run writes it
    (path,) = write_alignment_samples(tmp_path, [_Outcome("level", "average",
                                                          {"ieu_samples": rec.raw})])
    assert path == tmp_path / "alignments" / "level-average-ieu.csv"
    rows = read_csv(path)
    assert list(rows[0]) == list(RAW_COLUMNS)
    assert rows == [{k: csv_cell(v) for k, v in u.items()} for u in used]

    # the CAN log, read back with python-can and decoded with the DBC
    db = load_dbc()
    frames: dict[int, dict[str, tuple[float, dict]]] = {}
    for m in can.LogReader(tmp_path / CAN_LOG):
        spec = db.get_message_by_frame_id(m.arbitration_id)
        if spec.name in COUNT_PARTS:
            sig = spec.decode(bytes(m.data), decode_choices=False)
            frames.setdefault(int(sig["Seq"]), {})[spec.name] = (m.timestamp, sig)
    decoded = []
    for seq in sorted(frames):
        f = frames[seq]
        g, a, b, tm = (f[p][1] for p in COUNT_PARTS)
        decoded.append({"seq": seq, "t_s": f["IEU_TIMER"][0], "timer": tm["Timer"],
                        "flags": tm["Flags"], "gyro1": g["Gyro1"], "gyro2": g["Gyro2"],
                        "gyro3": g["Gyro3"], "A1S1": a["A1S1"], "A1S2": a["A1S2"],
                        "A2S1": a["A2S1"], "A2S2": b["A2S2"], "A3S1": b["A3S1"],
                        "A3S2": b["A3S2"]})
    decoded = [d for d in decoded if d["seq"] in {u["seq"] for u in used}]
    assert len(decoded) == len(used)
    for d, u in zip(decoded, used, strict=True):
        assert d["t_s"] == pytest.approx(u["t_s"], abs=1e-6)  # the log keeps microseconds
        assert {k: v for k, v in d.items() if k != "t_s"} == \
            {k: v for k, v in u.items() if k != "t_s"}


def test_can_log_is_kept_when_the_run_stops(tmp_path: Path) -> None:
    cfg = load_config(seed=5)
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    try:
        with pytest.raises(RuntimeError, match="stopped"), can_log(tmp_path, st.ieu):
            st.ieu.status()
            raise RuntimeError("stopped")
        assert st.ieu.frame_hook is None
    finally:
        st.close()
        rack.close()
    assert len(list(can.LogReader(tmp_path / CAN_LOG))) == 2  # the command and its status
