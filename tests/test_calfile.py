"""The calibration file (laboratory.calfile) and `station apply` (laboratory.apply): a day's
file is valid against its schema, and applied to that day's alignment samples it recovers
the simulator's true body rate and gravity within the predicted sigma."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from laboratory.apply import RawFileError, apply_calibration, read_raw
from laboratory.calfile import CalibrationFile, CalibrationFileError, load, parse
from laboratory.isu.day import DayRequest, run_day
from laboratory.isu.spec import noise_spec
from station.config.isu import load_config

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = ROOT / "docs" / "calibration-file.schema.json"
DEG_HR = np.pi / 180.0 / 3600.0
G0 = 9.80665
K = 4.0  # sigmas


@pytest.fixture(scope="module")
def day(tmp_path_factory):
    """A full virtual day (seed 2024) and the rack it ran on (its world knows the truth)."""
    out = tmp_path_factory.mktemp("calday")
    racks: list = []
    cfg = load_config(seed=2024)
    run_day(DayRequest(cfg, out, quiet=True), Console(quiet=True), rack_hook=racks.append)
    return out, racks[0].world, cfg


def test_day_writes_a_valid_calibration_file(day):
    out, _, _ = day
    doc = json.loads((out / "calibration.json").read_text())
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.Draft202012Validator(json.loads(SCHEMA.read_text())).validate(doc)
    run = json.loads((out / "run.json").read_text())
    assert doc["unit"] == run["unit"]
    assert doc["validity"]["run_uid"] == run["run_uid"]
    assert doc["validity"]["date"] == run["started_utc"][:10]
    sheet = json.loads((out / "sheets" / "calibration_results.json").read_text())
    assert [(c["instrument"], c["parameter"], c["value"], c["sigma"]) for c in doc["constants"]] \
        == [(r["instrument"], r["parameter"], r["estimate"], r["sigma"]) for r in sheet["rows"]]
    cal = load(out / "calibration.json")
    assert doc["covariance"]["kind"] == "full"
    # the full covariance's diagonal is the sheet's predicted variance, and it is correlated
    sig = np.array([cal.sigmas[r] for r in cal.order])
    assert np.allclose(np.sqrt(np.diag(cal.covariance)), sig, rtol=1e-6)
    corr = cal.covariance / np.outer(sig, sig)
    assert np.all(np.abs(corr) <= 1 + 1e-9)
    assert np.max(np.abs(corr - np.eye(len(sig)))) > 0.5
    assert "gyro1 J" in doc["covariance"]["note"]  # separate experiments: variance only


def _means(cal: CalibrationFile, path: Path) -> np.ndarray:
    """Mean body rate (deg/hr) and specific force (micro-g) over the record, B1 B2 B3."""
    c = apply_calibration(cal, read_raw(path))
    t = c.dt.sum()
    return np.concatenate([c.dtheta.sum(0) / t / DEG_HR,
                           (c.force * c.dt[:, None]).sum(0) / t / (G0 * 1e-6)])


def _calibration_sigma(cal: CalibrationFile, path: Path) -> np.ndarray:
    """The calibration's covariance carried through the inverse models (central
    differences, one sigma per step)."""
    jac = np.zeros((6, len(cal.order)))
    for i, key in enumerate(cal.order):
        h = float(np.sqrt(cal.covariance[i, i])) or 1e-12
        plus, minus = dict(cal.values), dict(cal.values)
        plus[key] += h
        minus[key] -= h
        jac[:, i] = (_means(replace(cal, values=plus), path)
                     - _means(replace(cal, values=minus), path)) / (2 * h)
    return np.sqrt(np.diag(jac @ cal.covariance @ jac.T))


@pytest.mark.parametrize("record", ["level-average", "gyrocompass-average"])
def test_apply_recovers_the_true_rate_and_gravity(day, record):
    out, world, cfg = day
    path = out / "alignments" / f"{record}-ieu.csv"
    cal = load(out / "calibration.json")
    raw = read_raw(path)
    comp = apply_calibration(cal, raw)
    t_mid = raw.extra["t_s"] - 0.5 * comp.dt  # a sample's stamp is its closing latch
    _, w_true, a_true = world.kinematics(t_mid)
    weights = comp.dt[:, None] / comp.dt.sum()
    truth = np.concatenate([(w_true * weights).sum(0) / DEG_HR,
                            (a_true * weights).sum(0) / (G0 * 1e-6)])
    got = _means(cal, path)
    # predicted sigma: the calibration's, and the record's own noise (random walk, random
    # drift since the calibration, one pulse of quantization; accelerometer white noise)
    nz = noise_spec(cfg)
    span = float(comp.dt.sum())
    dphi = cal.values[("gyro1", "DeltaPhi")] * 3600.0  # arcsec = deg/hr s
    gyro_noise = np.sqrt(nz.gyro_arw_deg_rt_hr**2 / (span / 3600.0)
                         + nz.gyro_drift_sigma_deg_hr**2 + (dphi / span) ** 2)
    accel_noise = nz.accel_white_micro_g_rt_hz / np.sqrt(span)
    noise = np.array([gyro_noise] * 3 + [accel_noise] * 3)
    sigma = np.hypot(_calibration_sigma(cal, path), noise)
    z = (got - truth) / sigma
    assert np.all(np.abs(z) < K), (got - truth, sigma)
    # and the sigma is the laboratory's, not a loose bound: < 0.05 deg/hr, < 30 micro-g
    assert np.all(sigma[:3] < 0.05) and np.all(sigma[3:] < 30.0)
    # the Earth rate and gravity themselves were recovered (magnitudes)
    assert abs(np.linalg.norm(got[:3]) - 15.041) < 0.1
    assert abs(np.linalg.norm(got[3:]) * 1e-6 * G0 - np.linalg.norm(a_true[0])) < 3e-4


def _bad(day, tmp_path: Path, edit) -> Path:
    doc = json.loads((day[0] / "calibration.json").read_text())
    edit(doc)
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(doc))
    return p


def _set_value(doc: dict, inst: str, par: str, v: object) -> None:
    for c in doc["constants"]:
        if (c["instrument"], c["parameter"]) == (inst, par):
            c["value"] = v


@pytest.mark.parametrize("edit, field", [
    (lambda d: d.pop("unit"), "unit: missing"),
    (lambda d: d.update(schema_version=3), "schema_version: 3 is not supported"),
    (lambda d: d["validity"].pop("run_uid"), "validity.run_uid: missing"),
    (lambda d: d["ieu"].update(timer_period_s=0), "ieu.timer_period_s"),
    (lambda d: d["constants"][3].update(value="x"), "constants[3].value (gyro1 G.B3)"),
    (lambda d: d["constants"][0].update(parameter="Z"), "constants[0].parameter"),
    (lambda d: d["covariance"]["matrix"].pop(), "covariance.matrix"),
    (lambda d: d["covariance"].update(kind="some"), "covariance.kind"),
])
def test_bad_files_are_refused_naming_the_field(day, tmp_path, edit, field):
    with pytest.raises(CalibrationFileError) as e:
        load(_bad(day, tmp_path, edit))
    assert field in str(e.value) and "bad.json" in str(e.value)


def test_missing_constants_refused_by_name(day, tmp_path):
    def drop(d: dict) -> None:
        _set_value(d, "gyro2", "R", None)
        d["covariance"]["kind"] = "diagonal"
        d["covariance"]["order"] = []
        d["covariance"]["matrix"] = []

    cal = load(_bad(day, tmp_path, drop))
    raw = read_raw(day[0] / "alignments" / "level-average-ieu.csv")
    with pytest.raises(CalibrationFileError, match="constants: no value for gyro2 R$"):
        apply_calibration(cal, raw)


def test_raw_file_missing_a_column_refused(day, tmp_path):
    src = (day[0] / "alignments" / "level-average-ieu.csv").read_text().splitlines()
    p = tmp_path / "raw.csv"
    p.write_text("\n".join(line.rsplit(",", 1)[0] for line in src) + "\n")
    with pytest.raises(RawFileError, match=r"raw.csv: missing column\(s\) A3S2"):
        read_raw(p)


def test_parse_refuses_non_object():
    with pytest.raises(CalibrationFileError, match="x.json: not a JSON object"):
        parse([1], Path("x.json"))


def test_station_apply_command(day, tmp_path):
    out = day[0]
    raw = out / "alignments" / "level-average-ieu.csv"
    target = tmp_path / "comp.csv"
    r = subprocess.run([sys.executable, "-m", "laboratory.cli", "apply",
                        str(out / "calibration.json"), str(raw), "--out", str(target)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert "600 samples, 300.0 s" in r.stdout
    lines = target.read_text().splitlines()
    assert lines[0] == ("seq,t_s,flags,dt_s,dtheta_B1_rad,dtheta_B2_rad,dtheta_B3_rad,"
                        "f_B1_mps2,f_B2_mps2,f_B3_mps2")
    assert len(lines) == 601
    comp = apply_calibration(load(out / "calibration.json"), read_raw(raw))
    first = [float(x) for x in lines[1].split(",")[3:]]
    assert first == [comp.dt[0], *comp.dtheta[0], *comp.force[0]]
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    r = subprocess.run([sys.executable, "-m", "laboratory.cli", "apply", str(bad), str(raw)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [f"error: {bad}: format: missing"]


def test_partial_day_writes_a_file_that_apply_refuses_by_name(day, tmp_path):
    """A day that determines nothing still writes a valid file; applying it names what
    is missing."""
    out = tmp_path / "part"
    run_day(DayRequest(load_config(seed=11), out, only=("II-11",), positions=(7,),
                       quiet=True), Console(quiet=True))
    doc = json.loads((out / "calibration.json").read_text())
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.Draft202012Validator(json.loads(SCHEMA.read_text())).validate(doc)
    assert doc["covariance"]["kind"] == "diagonal"
    assert doc["covariance"]["note"] == "no constant of the calibration program determined"
    cal = load(out / "calibration.json")
    raw = read_raw(day[0] / "alignments" / "level-average-ieu.csv")
    with pytest.raises(CalibrationFileError, match=r"no value for gyro1 DeltaPhi, .*accel3 D3$"):
        apply_calibration(cal, raw)


def test_align_that_calibrates_first_writes_the_calibration_file(tmp_path):
    """`station align` without --calibration measures a day first: its record holds that
    calibration's file too, with the Calibration Results Sheet's constants."""
    from laboratory.isu.align import AlignRequest, run_align

    out = tmp_path / "align"
    run_align(AlignRequest(load_config(seed=2025), out, "mirror", quiet=True),
              Console(quiet=True))
    cal = load(out / "calibration.json")
    sheet = json.loads((out / "sheets" / "calibration_results.json").read_text())
    rows = {(r["instrument"], r["parameter"]): r for r in sheet["rows"]
            if r["estimate"] is not None}
    assert len(rows) == 69 and set(cal.values) == set(rows)
    for key, r in rows.items():
        assert (cal.values[key], cal.sigmas[key]) == (r["estimate"], r["sigma"]), key
    run = json.loads((out / "run.json").read_text())
    assert cal.doc["unit"]["isu"] == run["unit"]["isu"]
