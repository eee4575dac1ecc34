"""The bench scripts still run against the station they measure: each imports, and the two
that had fallen behind it run whole (bench/config_corners.py passed the CIGTF config's
limit tables to the simulation; bench/hil_latency.py asked the served IEU for a period it
refuses). A bench that fails only when someone needs its figures is found here instead."""

from __future__ import annotations

import importlib.util
import os
import runpy
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "bench"
SCRIPTS = sorted(p for p in BENCH.glob("*.py"))
# the scripts one runs (the others are modules they import: bench/_campaign.py, fuzz targets)
RUNNABLE = [p for p in SCRIPTS if 'if __name__ == "__main__":' in p.read_text()]


def _run(*args: str, timeout: float) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": f"{ROOT}:{ROOT / 'tests'}"}
    return subprocess.run([sys.executable, *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout, env=env)


def test_there_are_bench_scripts():
    assert len(SCRIPTS) >= 20, [p.name for p in SCRIPTS]


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.name)
def test_each_bench_script_imports(path, monkeypatch):
    """Every name a script imports still exists (its main does not run on import)."""
    monkeypatch.syspath_prepend(str(ROOT / "tests"))
    monkeypatch.syspath_prepend(str(BENCH))
    monkeypatch.syspath_prepend(str(ROOT))
    spec = importlib.util.spec_from_file_location(f"bench_{path.stem}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)  # its dataclasses look it up there
    spec.loader.exec_module(module)


def _run_in_process(path: Path, args: list[str], monkeypatch, cwd: Path) -> int | str | None:
    """``python bench/<path> ARGS`` in this process (its ``__main__`` block, in ``cwd``):
    the code of the SystemExit it must end with."""
    monkeypatch.chdir(cwd)
    monkeypatch.syspath_prepend(str(ROOT / "tests"))
    monkeypatch.syspath_prepend(str(BENCH))
    monkeypatch.syspath_prepend(str(ROOT))
    monkeypatch.setattr(sys, "argv", [str(path), *args])
    with pytest.raises(SystemExit) as exit_:
        runpy.run_path(str(path), run_name="__main__")
    return exit_.value.code


def test_there_are_runnable_bench_scripts():
    assert len(RUNNABLE) >= 20, [p.name for p in RUNNABLE]


@pytest.mark.parametrize("path", RUNNABLE, ids=lambda p: p.name)
def test_each_bench_script_has_help(path, monkeypatch, tmp_path, capsys):
    """``--help`` prints the usage and exits 0 without running anything: no file or
    directory appears where it runs (one script used to make a directory named --help)."""
    assert _run_in_process(path, ["--help"], monkeypatch, tmp_path) == 0
    out = capsys.readouterr().out
    assert "usage:" in out, out
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args", [
    ["alignment_mc.py", "notanumber"],
    ["ieu_stream.py", "4h"],
    ["random_calibration_days.py", "out"],  # no SEED: it made out/ and ran nothing
    ["esg_alignment.py", "remount", "2"],  # START goes with pickoff3m2 only
    ["config_corners.py", "isu", "nolab"],
    ["calibration_mc.py", "0"],
    ["gate_cost.py", "--bogus"],
], ids=" ".join)
def test_bench_script_refuses_bad_input(args, monkeypatch, tmp_path, capsys):
    """A bad argument is a one-line error on stderr and exit 2, before any work."""
    assert _run_in_process(BENCH / args[0], args[1:], monkeypatch, tmp_path) == 2
    err = capsys.readouterr().err
    assert "error:" in err.splitlines()[-1], err
    assert list(tmp_path.iterdir()) == []


def test_config_corners_cigtf_runs_whole():
    """The three CIGTF corners complete (each a whole gyrocompassing test)."""
    r = _run("bench/config_corners.py", "cigtf", timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    lines = [ln for ln in r.stdout.splitlines() if ln.strip()]
    assert len(lines) == 3 and all("completed: operating theta" in ln for ln in lines), r.stdout


def test_hil_latency_measures_replies_and_ieu_frames():
    """A served rack at speed 1: replies to 40 queries and 1 s of IEU frames at the bench's
    default period, which the served IEU accepts (the figures themselves are not asserted:
    no timed tests)."""
    r = _run("bench/hil_latency.py", "40", "1", timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "reply lateness" in r.stdout and "IEU frame lateness" in r.stdout, r.stdout
    frames = next(ln for ln in r.stdout.splitlines() if ln.startswith("IEU frame lateness"))
    assert int(frames.split("n=")[1].split()[0]) > 0, frames
