"""Regression baselines (`station regress save/check`, laboratory/regress.py) and the pytest
plugin's helpers (laboratory/pytest_plugin.py): a same-config rerun passes with every sheet
repeated exactly; a config that shifts one accelerometer bias by about 10 combined sigma
fails with exit 1 and a JUnit failure naming that constant and its z."""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from laboratory import regress
from laboratory.pytest_plugin import PROCEDURES, Record, assert_within_sigma, virtual_station

SEED = 31
SHIFT_G = 5e-5  # accel1's D0 moved from 1.2e-4 g: its sigma is about 3.4e-6 g


def station(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "laboratory.cli", *args],
                          capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def baseline(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A full day's run and the baseline saved from it by the command line."""
    d = tmp_path_factory.mktemp("regress")
    _, day = PROCEDURES["day"]
    day(virtual_station("isu", seed=SEED), d / "base", {"quiet": True})
    r = station("regress", "save", str(d / "base"), str(d / "baseline.json"))
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"baseline written: {d / 'baseline.json'} (")
    return d / "base", d / "baseline.json"


def _junit(path: Path) -> list[ET.Element]:
    root = ET.parse(path).getroot()
    assert root.tag == "testsuites"
    return list(root.iter("testcase"))


def test_baseline_holds_constants_and_sheets(baseline: tuple[Path, Path]) -> None:
    run_dir, bfile = baseline
    b = json.loads(bfile.read_text())
    ident = json.loads((run_dir / "run.json").read_text())
    assert (b["format"], b["version"], b["seed"], b["config_digest"]) == (
        regress.FORMAT, regress.VERSION, SEED, ident["config_digest"])
    names = {c["name"] for c in b["constants"]}
    assert "accel1.D0" in names and "mirror/average alignment.az error" in names
    assert len([n for n in names if "alignment" not in n]) == 3 * 16 + 3 * 7
    d0 = next(c for c in b["constants"] if c["name"] == "accel1.D0")
    results = json.loads((run_dir / "results.json").read_text())
    row = next(r for r in results["calibration"]
               if (r["instrument"], r["parameter"]) == ("accel1", "D0"))
    assert (d0["estimate"], d0["sigma"], d0["units"]) == (row["estimate"], row["sigma"], "g")
    assert b["sheets"]["check_II-11"][0] == {"number": "1", "reading": None, "t_sim": json.loads(
        (run_dir / "sheets" / "check_II-11.json").read_text())["steps"][0]["t_sim"]}


def test_same_config_rerun_passes(baseline: tuple[Path, Path], run_procedure, station_lab,
                                  tmp_path: Path) -> None:
    _, bfile = baseline
    rec: Record = run_procedure("day", station_lab("isu", seed=SEED))
    r = station("regress", "check", str(rec.dir), str(bfile), "--junit",
                str(tmp_path / "j.xml"))
    assert r.returncode == 0, r.stdout + r.stderr
    cases = _junit(tmp_path / "j.xml")
    b = json.loads(bfile.read_text())
    assert len(cases) == len(b["constants"]) + len(b["sheets"])
    assert not [c for c in cases if c.find("failure") is not None]
    assert not [c for c in cases if c.find("skipped") is not None]  # a replay: sheets held
    assert r.stdout.strip() == f"{len(cases)} checked, 0 regressions, 0 skipped"


def test_shifted_constant_fails_and_is_named(baseline: tuple[Path, Path], run_procedure,
                                            station_lab, tmp_path: Path) -> None:
    _, bfile = baseline
    st = station_lab("isu", seed=SEED, overrides={"isu.accels.0.D0_g": 1.2e-4 + SHIFT_G})
    rec = run_procedure("day", st)
    r = station("regress", "check", str(rec.dir), str(bfile), "--junit",
                str(tmp_path / "j.xml"))
    assert r.returncode == 1, r.stdout + r.stderr
    failed = [c for c in _junit(tmp_path / "j.xml") if c.find("failure") is not None]
    assert [c.get("name") for c in failed] == ["accel1.D0"]
    (case,) = failed
    z = float(case.find("properties/property[@name='z']").get("value"))  # type: ignore[union-attr]
    b = {c["name"]: c for c in json.loads(bfile.read_text())["constants"]}
    new = rec.row("accel1", "D0")
    combined = (b["accel1.D0"]["sigma"] ** 2 + new["sigma"] ** 2) ** 0.5
    # the shift seen as z (same seed: the noise is the same draw, so z is the shift alone)
    assert_within_sigma(z * combined, SHIFT_G, combined, k=1, name="the shift")
    assert case.find("failure").get("message").startswith(  # type: ignore[union-attr]
        f"accel1.D0: z = {z:+.2f} beyond 4 sigma")
    assert r.stdout.splitlines()[-1].endswith("1 regressions, "
                                              f"{len(json.loads(bfile.read_text())['sheets'])} "
                                              "skipped")  # another digest: sheets not replays


def test_a_wider_sigma_lets_the_shift_pass(baseline: tuple[Path, Path]) -> None:
    _, bfile = baseline
    b = json.loads(bfile.read_text())
    moved = dict(b)
    moved["constants"] = [dict(c, estimate=c["estimate"] + 5 * c["sigma"] * 2 ** 0.5)
                          if c["name"] == "gyro2.B_I" else c for c in b["constants"]]
    cases = {c.name: c for c in regress.check(baseline[0], _write(bfile.parent / "m.json",
                                                                   moved), k=4.0)}
    assert cases["gyro2.B_I"].failure is not None
    assert cases["gyro2.B_I"].z == pytest.approx(-5.0)
    wide = {c.name: c for c in regress.check(baseline[0], bfile.parent / "m.json", k=6.0)}
    assert wide["gyro2.B_I"].failure is None


def _write(p: Path, obj: object) -> Path:
    p.write_text(json.dumps(obj))
    return p


def test_refusals_are_one_line(baseline: tuple[Path, Path], tmp_path: Path) -> None:
    run_dir, bfile = baseline
    bad = _write(tmp_path / "bad.json", {"format": "something else"})
    r = station("regress", "check", str(run_dir), str(bad))
    assert r.returncode == 2
    assert r.stderr == f"error: {bad}: format: not a {regress.FORMAT} file\n"
    other = json.loads(bfile.read_text())
    other["unit"] = dict(other["unit"], gyro1="GYRO-999")
    r = station("regress", "check", str(run_dir), str(_write(tmp_path / "o.json", other)))
    assert r.returncode == 2 and r.stderr.startswith(f"error: {tmp_path / 'o.json'}: unit: ")
    r = station("regress", "save", str(tmp_path / "nowhere"), str(tmp_path / "b.json"))
    assert r.returncode == 2
    assert r.stderr == f"error: {tmp_path / 'nowhere'}: no such run directory\n"


def test_assert_within_sigma() -> None:
    assert assert_within_sigma(1.0, 0.5, 0.25) == pytest.approx(2.0)
    with pytest.raises(AssertionError, match=r"^B_I = 2 is \+4.00 sigma from 1 \(sigma 0.25; "
                                             r"allowed 3\)$"):
        assert_within_sigma(2.0, 1.0, 0.25, k=3, name="B_I")
    with pytest.raises(AssertionError, match="sigma must be a positive number"):
        assert_within_sigma(1.0, 1.0, 0.0)
