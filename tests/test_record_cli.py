"""Every everyday mistake of issue 12, before and after, on a finished run's record: one
line on stderr, exit 2, no traceback, and the record byte for byte as it was. Fresh run
directories, --resume of finished, empty, misspelt and malformed runs, --version, and the
gyrocompass alignment refused near a pole."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from rich.console import Console
from typer.testing import CliRunner

from laboratory.cli import app
from laboratory.compare import differences
from laboratory.isu.day import DayRequest, run_day
from laboratory.rundir import fresh
from station.config.isu import load_config

REPO = Path(__file__).resolve().parents[1]
QUIET = Console(quiet=True)
SEED = 11
SHORT = ("--only", "II-11", "--positions", "7")
UNWRITABLE = Path("/proc/station-record-test/run")  # not creatable, even by root


def tree(d: Path) -> dict[str, str]:
    """Every file under ``d`` with its sha256."""
    return {str(p.relative_to(d)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(d.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished short day (turn-on, survey, positions 7 and 8, computations, mirror)."""
    d = tmp_path_factory.mktemp("finished") / "D"
    run_day(DayRequest(load_config(seed=SEED), d, only=("II-11",), positions=(7,),
                       quiet=True), QUIET)
    return d


@pytest.fixture
def cli(tmp_path, monkeypatch):
    """Run `station ...` in-process from an empty working directory."""
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()

    def invoke(*args: str):
        return runner.invoke(app, [str(a) for a in args])

    return invoke


def refused(r, *words: str) -> None:
    """Exit 2 with exactly one line on stderr, nothing on stdout, no exception."""
    assert r.exit_code == 2, (r.exit_code, r.output)
    assert r.stdout == "" and r.stderr.count("\n") == 1 and r.stderr.startswith("error: ")
    assert not isinstance(r.exception, Exception) or isinstance(r.exception, SystemExit)
    for w in words:
        assert w in r.stderr, (w, r.stderr)


CASES = [
    (("day", "--only", "II-99", "--out", "{D}"), ("II-99",)),
    (("day", "--positions", "99", "--out", "{D}"), ("position(s) 99",)),
    (("day", "--out", "{D}"), ("already holds", "--resume {D}")),
    (("day", "--out", "{D}", "--only", "II-11"), ("already holds",)),
    (("day", "--seed", "-1", "--out", "{D}"), ("--seed",)),
    (("day", "--out", "{D}/journal.jsonl"), ("existing file",)),
    (("day", "--out", "{D}/results.json/run"), ("is a file",)),
    (("day", "--out", "{D}", "--resume", "{D}"), ("not both",)),
    (("day", "--resume", "{D}", "--seed", "5"), ("--seed 5 differs",)),
    (("day", "--resume", "{D}", "--only", "II-13"), ("--only II-13 differs",)),
    (("day", "--config", "{D}"), ("--config",)),
    (("align", "--method", "mirror", "--out", "{D}"), ("already holds",)),
    (("align", "--method", "sideways"), ("sideways",)),
    (("align", "--method", "level", "--estimator", "best"), ("best",)),
    (("align",), ("--method is required",)),
    (("align", "--method", "level", "--calibration", "{D}/nope"), ("no such directory",)),
    (("gyrocompass-test", "--seed", "-1"), ("--seed",)),
    (("gyrocompass-test", "--out", "{D}"), ("already holds",)),
    (("gyrocompass-test", "--out", "{D}/journal.jsonl"), ("existing file",)),
    (("gyrocompass-test", "--resume", "{D}"), ("`station day` run",)),
    (("gyrocompass-test", "--analyse", "{D}/nope"), ("no such directory",)),
    (("esg-calibration", "--seed", "-1"), ("--seed",)),
    (("esg-calibration", "--out", "{D}/sheets"), ("not empty",)),
    (("esg-calibration", "--resume", "{D}/sheets"), ("no journal",)),
    (("compare", "{D}", "{D}/nope"), ("no such run directory",)),
]


@pytest.mark.parametrize(("args", "words"), CASES, ids=[" ".join(c[0]) for c in CASES])
def test_everyday_mistakes_are_refused_and_touch_nothing(finished, cli, tmp_path, args,
                                                        words):
    before = tree(finished)
    r = cli(*(a.replace("{D}", str(finished)) for a in args))
    refused(r, *(w.replace("{D}", str(finished)) for w in words))
    assert tree(finished) == before
    assert list(tmp_path.iterdir()) == []  # no runs/ made in the working directory


@pytest.mark.parametrize("command", ["day", "gyrocompass-test", "esg-calibration"])
def test_unwritable_out_and_missing_resume_directory(cli, tmp_path, command):
    extra = SHORT if command == "day" else ()
    refused(cli(command, "--out", UNWRITABLE, *extra), "cannot create the run directory",
            str(UNWRITABLE))
    refused(cli(command, "--resume", tmp_path / "misspelt"), "no such directory")
    (tmp_path / "empty").mkdir()
    refused(cli(command, "--resume", tmp_path / "empty"), "no journal")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty"]
    assert list((tmp_path / "empty").iterdir()) == []


def test_resume_of_a_finished_run_says_so_and_measures_nothing(finished, cli):
    before = tree(finished)
    r = cli("day", "--resume", finished, "--quiet")
    assert r.exit_code == 0 and "complete" in r.stdout and r.stderr == ""
    assert tree(finished) == before


def _unfinished(finished: Path, d: Path) -> Path:
    """A copy of the finished day as a kill after its results would leave it: the
    journal without its end note."""
    shutil.copytree(finished, d)
    lines = (d / "journal.jsonl").read_bytes().splitlines(keepends=True)
    assert json.loads(lines[-1])["event"] == "end"
    (d / "journal.jsonl").write_bytes(b"".join(lines[:-1]))
    return d


@pytest.mark.parametrize(("line", "why"), [
    (b"garbage\n", "not a JSON record"),
    (b"42\n", "not a record"),
    (b'{"kind": "teleport"}\n', "unknown record kind"),
    (b'{"kind":"block","key":"II-11","data":{},"sheets":["../../X"]}\n',
     "outside the run directory"),
])
def test_malformed_journal_line_stops_the_resume_naming_it(finished, cli, tmp_path, line,
                                                          why):
    d = _unfinished(finished, tmp_path / "X")
    j = d / "journal.jsonl"
    lines = j.read_bytes().splitlines(keepends=True)
    j.write_bytes(b"".join(lines[:20] + [line] + lines[20:]))
    before = tree(d)
    # over links too: the journal is refused before any link is opened
    for extra in ((), ("--links", str(tmp_path / "links"))):
        r = cli("day", "--resume", d, "--quiet", *extra)
        refused(r, f"{j}:21: ", why)
        assert tree(d) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["X"]
    assert not (tmp_path / "X.json").exists() and not (tmp_path.parent / "X.json").exists()


def test_torn_last_line_is_set_aside_and_the_day_finishes_identical(finished, cli, tmp_path):
    d = _unfinished(finished, tmp_path / "T")
    j = d / "journal.jsonl"
    whole = j.read_bytes()
    torn = b'{"chart":"III-2","kind":"step","reading":{"alpha'
    j.write_bytes(whole + torn)
    r = cli("day", "--resume", d, "--quiet")
    assert r.exit_code == 0, r.output
    assert (d / "journal.jsonl.torn-1").read_bytes() == torn
    after = j.read_bytes()
    assert after.startswith(whole)  # appended after the whole records, never rewritten
    added = [json.loads(x) for x in after[len(whole):].splitlines()]
    assert [r.get("event") for r in added] == ["resume", "end"]
    assert added[0]["torn_line_to"] == "journal.jsonl.torn-1"
    assert differences(finished, d) == []


def test_a_journal_recorded_over_links_resumes_only_over_links(finished, cli, tmp_path):
    d = _unfinished(finished, tmp_path / "L")
    j = d / "journal.jsonl"
    lines = j.read_bytes().splitlines(keepends=True)
    start = json.loads(lines[0])
    start["session"] = "s-1"
    j.write_bytes(json.dumps(start).encode() + b"\n" + b"".join(lines[1:]))
    before = tree(d)
    refused(cli("day", "--resume", d, "--quiet"), "recorded over links", "--links")
    assert tree(d) == before


def test_each_run_without_out_gets_a_fresh_directory(cli, tmp_path):
    outs = []
    for _ in range(2):
        r = cli("day", "--seed", SEED, *SHORT, "--quiet")
        assert r.exit_code == 0, r.output
        outs.append(Path(r.stdout.strip().rsplit("record in ", 1)[1]))
    a, b = (tmp_path / o for o in outs)
    assert a != b and a.parent == b.parent == tmp_path / "runs" / "day"
    assert a.name.endswith(f"-seed{SEED}") or f"-seed{SEED}-" in a.name
    assert differences(a, b) == []  # same seed and config: the same record


def test_fresh_directories_are_unique_within_a_second(tmp_path):
    import datetime as dt

    t = dt.datetime(2024, 5, 1, 12, 0, 7, tzinfo=dt.UTC)
    got = [fresh(tmp_path / "runs" / "day", 3, t).name for _ in range(3)]
    assert got == ["20240501T120007Z-seed3", "20240501T120007Z-seed3-2",
                   "20240501T120007Z-seed3-3"]


def _station(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "laboratory.cli", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(REPO)})


def test_the_station_command_itself_gives_one_line_errors_and_its_version(tmp_path):
    """Through `python -m laboratory.cli` (the `station` entry point): the parser's own
    mistakes (a bad number, an unknown option) are one line too."""
    from importlib.metadata import version

    r = _station("--version", cwd=tmp_path)
    assert r.returncode == 0 and r.stdout == f"station {version('isu-station')}\n"
    for args, word in ((("day", "--positions", "abc"), "'--positions'"),
                       (("day", "--bogus"), "--bogus"),
                       (("esg-calibration", "--seed", "x"), "'--seed'"),
                       (("day", "--only", "II-99"), "II-99")):
        r = _station(*args, cwd=tmp_path)
        assert r.returncode == 2 and r.stdout == "", r
        assert r.stderr.count("\n") == 1 and r.stderr.startswith("error: ") and word in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_gyrocompass_alignment_near_a_pole_is_refused_or_skipped(cli, tmp_path):
    """At latitude 89 (beyond the 88.1 deg where the gyros' noise alone leaves a 1 deg
    azimuth sigma) `station align --method gyrocompass` is refused up front and the day
    skips that alignment, saying why in results.json; mirror and level still run."""
    from laboratory.isu.align import gyrocompass_latitude_limit_deg

    cfg = tmp_path / "pole.toml"
    cfg.write_text("[site]\nlatitude_deg = 89.0\n")
    assert 87.5 < gyrocompass_latitude_limit_deg(load_config()) < 88.5
    assert gyrocompass_latitude_limit_deg(load_config(cfg)) == gyrocompass_latitude_limit_deg(
        load_config())
    refused(cli("align", "--method", "gyrocompass", "--config", cfg, "--out", tmp_path / "A"),
            "site.latitude_deg = 89", "gyrocompass")
    assert not (tmp_path / "A").exists()
    r = cli("day", "--config", cfg, "--out", tmp_path / "D", "--quiet")
    assert r.exit_code == 0, r.output
    res = json.loads((tmp_path / "D" / "results.json").read_text())
    methods = [(a["method"], a.get("estimator")) for a in res["alignment"]]
    assert methods == [("mirror", "average"), ("level", "average"), ("level", "posterior"),
                       ("gyrocompass", None)]
    assert "site.latitude_deg = 89" in res["alignment"][-1]["skipped"]
    assert not any(s.name.startswith("alignment_results_gyrocompass")
                   for s in (tmp_path / "D" / "sheets").iterdir())


def test_resume_with_another_config_is_refused_at_the_first_differing_step(finished, cli,
                                                                           tmp_path):
    """The replay checks each step against the journal: another latitude changes the
    survey's readings, and the resume stops there (exit 2) with nothing measured after."""
    d = _unfinished(finished, tmp_path / "C")
    cfg = tmp_path / "elsewhere.toml"
    cfg.write_text("[site]\nlatitude_deg = 40.0\n")
    before = (d / "journal.jsonl").read_bytes()
    r = cli("day", "--resume", d, "--config", cfg, "--quiet")
    refused(r, f"{d / 'journal.jsonl'}:", "was the seed, config or code changed")
    line = int(r.stderr.split("journal.jsonl:")[1].split(":")[0])
    rec = json.loads(before.splitlines()[line - 1])
    assert rec["kind"] == "step" and rec["chart"] in ("I-1", "I-2")
    after = (d / "journal.jsonl").read_bytes()
    assert after.startswith(before)
    assert [json.loads(x)["event"] for x in after[len(before):].splitlines()] == ["resume"]


def test_a_run_directory_being_recorded_is_not_resumed_twice(finished, cli, tmp_path):
    from laboratory.rundir import recording

    d = _unfinished(finished, tmp_path / "busy")
    before = tree(d)
    with recording(d):  # another run holds it
        refused(cli("day", "--resume", d, "--quiet"), "another run is recording in it")
    assert tree(d) == before
