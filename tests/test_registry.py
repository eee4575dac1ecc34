"""The laboratory registry: the three laboratories and a fourth added from outside.

tests/toylab is a toy laboratory (one thermometer, one check-sheet) that no project module
names. It is added by one registry entry (``STATION_LABORATORIES``), and then `station
labs`, `station check --station toy`, `station serve --station toy` and its own command
reach it: nothing else was edited. Its result is held to its truth within its predicted
sigma, and that sigma is checked over seeds.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
from hil_helpers import serving

from laboratory import registry

TESTS = Path(__file__).resolve().parent
ENTRY = "toy=toylab.lab:LAB"


@pytest.fixture
def toy(monkeypatch):
    """The toy laboratory registered as a user would: one entry in the environment."""
    monkeypatch.setenv(registry.ENV_VAR, ENTRY)
    monkeypatch.syspath_prepend(str(TESTS))
    registry._loaded.pop("toy", None)
    yield registry.get("toy")
    registry._loaded.pop("toy", None)


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env[registry.ENV_VAR] = ENTRY
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), env.get("PYTHONPATH", "")])
    return env


def _station(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "laboratory.cli", *args], env=_env(),
                          capture_output=True, text=True, timeout=timeout,
                          stdin=subprocess.DEVNULL)


def test_the_three_laboratories_are_registered_by_name():
    assert registry.names()[:3] == ["isu", "cigtf", "esg"]
    for name in ("isu", "cigtf", "esg"):
        lab = registry.get(name)
        assert lab.name == name and lab.drivers()


def test_an_unknown_or_broken_entry_is_named(monkeypatch):
    with pytest.raises(registry.UnknownLaboratory, match="unknown laboratory 'nope'.*isu"):
        registry.get("nope")
    monkeypatch.setenv(registry.ENV_VAR, "bad=no.such.module:LAB")
    with pytest.raises(registry.UnknownLaboratory, match="laboratory 'bad': cannot load"):
        registry.get("bad")
    monkeypatch.setenv(registry.ENV_VAR, "garbage")
    with pytest.raises(registry.UnknownLaboratory, match="not name=module:attribute"):
        registry.names()


def test_cli_lists_and_checks_the_toy_laboratory(tmp_path):
    r = _station("labs")
    assert r.returncode == 0 and "toy\ttoy laboratory" in r.stdout, r.stderr
    r = _station("check", "--station", "toy", "--json")
    assert r.returncode == 0, r.stderr
    (row,) = json.loads(r.stdout)
    assert row["instrument"] == "thermometer" and row["ok"]
    assert row["identity"].startswith("TOY-LAB,THERMOMETER")
    r = _station("check", "--station", "nope")
    assert r.returncode == 2 and "unknown laboratory 'nope'" in r.stderr


def test_toy_procedure_in_virtual_time_meets_its_truth(toy, tmp_path):
    """One run through the CLI; its error against the world's truth is within 4 sigma."""
    from toylab.lab import run_bath  # the laboratory's own entry point

    r = _station("toy-bath", "--seed", "11", "--out", str(tmp_path / "run"))
    assert r.returncode == 0, r.stderr
    res = json.loads((tmp_path / "run" / "toy.json").read_text())
    assert abs(res["mean_k"] - res["truth_k"]) < 4.0 * res["sigma_k"]
    assert (tmp_path / "run" / "sheets" / "check_T-1.json").exists()
    again = run_bath(11, tmp_path / "again")  # same seed, same record
    assert again == {k: res[k] for k in again}


def test_toy_predicted_sigma_is_honest_over_seeds(toy, tmp_path):
    from toylab.lab import run_bath

    z = [(r["mean_k"] - r["truth_k"]) / r["sigma_k"]
         for r in (run_bath(seed, tmp_path / f"s{seed}", n=12) for seed in range(40))]
    rms = math.sqrt(sum(x * x for x in z) / len(z))
    # a t(11) variable has variance 11/9; rms over 40 seeds lies in [0.75, 1.5] with
    # probability above 0.999 for honest sigmas
    assert 0.75 < rms < 1.5, rms


def test_toy_rack_served_checked_and_measured_over_links(toy, tmp_path, monkeypatch):
    monkeypatch.setenv("PYTHONPATH", _env()["PYTHONPATH"])  # for the server process
    with serving(tmp_path, ["--station", "toy", "--seed", "5", "--speed", "20"]) as (
            links, entries, _):
        assert [e.instrument for e in entries] == ["thermometer"]
        r = _station("check", "--station", "toy", "--links", str(links), "--json")
        assert r.returncode == 0, r.stderr
        assert json.loads(r.stdout)[0]["ok"]
        r = _station("toy-bath", "--seed", "5", "--links", str(links), "--readings", "4",
                     "--out", str(tmp_path / "served"))
        assert r.returncode == 0, r.stderr
    res = json.loads((tmp_path / "served" / "toy.json").read_text())
    assert res["served"]["station"] == "toy" and res["served"]["truth"] is True
    assert abs(res["mean_k"] - res["truth_k"]) < 5.0 * res["sigma_k"]


def test_an_installed_laboratory_runs_and_a_builtin_command_scans_no_package(tmp_path):
    """The toy laboratory installed as a package declares it (an entry point of
    ``station.laboratories``, no environment entry): `station labs` lists it and its own
    command runs. A command of the station or of a built-in laboratory starts without
    scanning the installed packages' metadata (issue 17): a scan there fails the run."""
    dist = tmp_path / "site" / "toylab_dist-0.1.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: toylab-dist\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[{registry.ENTRY_POINTS}]\n"
                                           "toy = toylab.lab:LAB\n")
    env = {k: v for k, v in os.environ.items() if k != registry.ENV_VAR}
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), str(tmp_path / "site"),
                                         env.get("PYTHONPATH", "")])

    def station(*args: str, code: str = "") -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-c", code + "import sys\nsys.argv = "
                               "['station', " + ", ".join(repr(a) for a in args) + "]\n"
                               "from laboratory.cli import main\nmain()\n"],
                              env=env, capture_output=True, text=True, timeout=120,
                              stdin=subprocess.DEVNULL)

    r = station("labs")
    assert r.returncode == 0 and "toy\ttoy laboratory" in r.stdout, r.stderr
    r = station("toy-bath", "--seed", "3", "--readings", "3", "--out", str(tmp_path / "run"))
    assert r.returncode == 0, r.stderr
    res = json.loads((tmp_path / "run" / "toy.json").read_text())
    assert abs(res["mean_k"] - res["truth_k"]) < 4.0 * res["sigma_k"]
    no_scan = ("import importlib.metadata as md\n"
               "def refuse(*a, **k):\n    raise SystemExit('installed packages scanned')\n"
               "md.entry_points = refuse\n")
    for args in (["report", "--help"], ["day", "--help"], ["compare", str(tmp_path),
                                                          str(tmp_path)]):
        r = station(*args, code=no_scan)
        assert "scanned" not in r.stderr, (args, r.stderr)
    r = station("toy-bath", "--help", code=no_scan)  # not a built-in command: scanned
    assert "installed packages scanned" in r.stderr
