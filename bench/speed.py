"""Speed of the station's commands, each run as a whole process as a user runs it (issue 17).

For each command (``station day --quiet``, ``station day`` with its ticks and tables shown
(``day-shown``, output to a file), ``station day --quiet`` into its default record directory
in a laboratory directory whose history grows by a run each repeat (``day-lab``: the
report's history section and the index at work), ``station gyrocompass-test``, ``station
esg-calibration``, ``station --help``), run ``--repeat`` times as ``python -m MODULE ...``,
MODULE the one the tree's pyproject names for its `station` script (laboratory.script now),
with PYTHONPATH set to the tree under test, it prints the minimum and median wall time of
the whole process, the time inside the run (results.json ``wall_seconds``, else the closing
line), lab time per wall second, the peak memory of the process (its own rusage) and its CPU
time with the children it reaped (the plot child, where the run reaps it before it exits:
a day since bfe0fda leaves the reaping to a thread its exit may overtake, and its child is
then not counted): a run's cpu s / CPUs is a floor under its
wall time that no overlap of the two processes gets below (the column is the median). Then,
where the tree has them, bench/ieu_stream.ieu_cost_per_sample(4.0) and
bench/gate_cost.gate_cost_ratio().

With ``--against REV`` it checks REV out in a temporary git worktree (removed at the end)
and runs both trees alternately, repeat by repeat (same machine, same moment; the order
alternates too), and prints both side by side with the ratios REV / this tree: on a shared,
noisy machine a ratio measured side by side is the figure that counts.

Each tree is byte-compiled first (compileall) and its commands run with bytecode caches
read, as after ``pip install`` or a user's first run: a machine with
PYTHONDONTWRITEBYTECODE set (this one) otherwise compiles every module of the station on
every start, 0.5-1 s that no user's run pays.

    python bench/speed.py [--repeat 5]
                          [--commands day,day-shown,day-lab,gyrocompass,esg,help]
                          [--against REV]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
COMMANDS: dict[str, list[str]] = {  # name -> arguments after `station` ({out}: a fresh dir)
    "day": ["day", "--seed", "1970", "--quiet", "--out", "{out}"],
    # the README's main job as a user runs it: the check-sheet ticks and tables shown
    "day-shown": ["day", "--seed", "1970", "--out", "{out}"],
    # `station day` as a laboratory runs it day after day: its default record directory
    # (runs/day/...) in the tree's own lab directory, whose history of the unit grows by
    # one run each repeat (the report's history section and the index read and write it)
    "day-lab": ["day", "--seed", "1970", "--quiet"],
    "gyrocompass": ["gyrocompass-test", "--out", "{out}"],
    "esg": ["esg-calibration", "--out", "{out}"],
    "help": ["--help"],
}
IN_LAB_DIR = {"day-lab"}  # run in scratch/lab-<tree>, kept across repeats
DEFAULT_CLI = "laboratory.cli"
CLOSING = re.compile(r"([0-9.]+) h simulated in ([0-9.]+) s")
NA = "n/a (not in this revision)"


@dataclass
class Sample:
    """One whole-process run of one command."""

    wall: float  # s, the whole process
    inside: float | None  # s, the run's own wall_seconds
    lab_s: float | None  # simulated seconds
    peak_mb: float  # the process's maximum resident set
    cpu: float  # s, user + system of the process and the children it reaped


def cli_module(root: Path) -> str:
    """The module of the tree's ``station`` script (pyproject [project.scripts]): run as
    ``python -m`` it is the command a user runs (laboratory.script now; laboratory.cli
    before issue 17's collector deferral, station.cli before issue 14)."""
    import tomllib

    try:
        doc = tomllib.loads((root / "pyproject.toml").read_text())
        return str(doc["project"]["scripts"]["station"]).split(":")[0]
    except (OSError, ValueError, KeyError):
        return DEFAULT_CLI


@dataclass
class Tree:
    """A source tree under test: its label and its root (PYTHONPATH)."""

    label: str
    root: Path
    cli: str = DEFAULT_CLI
    samples: dict[str, list[Sample]] = field(default_factory=dict)
    costs: dict[str, str] = field(default_factory=dict)


def _run_json(out: Path) -> tuple[float | None, float | None]:
    """(wall_seconds, sim_seconds) from the run directory's results (any top-level JSON
    file holding both), or (None, None)."""
    for f in sorted(out.glob("*.json")):
        try:
            d = json.loads(f.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(d, dict) and "wall_seconds" in d and "sim_seconds" in d:
            return float(d["wall_seconds"]), float(d["sim_seconds"])
    return None, None


def child_env(tree: Tree) -> dict[str, str]:
    """The environment a tree's command runs in: its root first on the path, bytecode
    caches used (PYTHONDONTWRITEBYTECODE dropped; ``byte_compile`` wrote them)."""
    env = dict(os.environ, PYTHONPATH=str(tree.root), STATION_OPERATOR="bench")
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env.pop("STATION_HISTORY_URL", None)  # day-lab: each lab directory's own history
    return env


def byte_compile(tree: Tree) -> None:
    """Every module of the tree compiled to its __pycache__, as pip install leaves it."""
    subprocess.run([sys.executable, "-m", "compileall", "-q", "-j", "0", "-x",
                    r"[/\\]\.git[/\\]", str(tree.root)], check=True,
                   stdout=subprocess.DEVNULL)


def run_once(tree: Tree, name: str, scratch: Path, i: int) -> Sample:
    """Run command ``name`` once in ``tree`` as a whole process; raise naming the command
    and the tree if it fails."""
    out = scratch / f"{tree.label}-{name}-{i}"
    args = [a.replace("{out}", str(out)) for a in COMMANDS[name]]
    env = child_env(tree)
    log = scratch / f"{tree.label}-{name}-{i}.log"
    cwd = scratch / f"lab-{tree.label}" if name in IN_LAB_DIR else scratch
    cwd.mkdir(exist_ok=True)
    with log.open("wb") as fh:
        t0 = time.perf_counter()
        p = subprocess.Popen([sys.executable, "-m", tree.cli, *args], cwd=cwd,
                             env=env, stdout=fh, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        p.returncode = os.waitstatus_to_exitcode(status)
    text = log.read_text(errors="replace")
    if p.returncode != 0:
        tail = text.strip().splitlines()[-1:] or [""]
        raise SystemExit(f"{name} in {tree.root}: exit {p.returncode}: {tail[0]}")
    inside, lab = _run_json(out) if out.exists() else (None, None)
    m = CLOSING.search(text)
    if m and inside is None:
        lab, inside = float(m.group(1)) * 3600.0, float(m.group(2))
    # wait4's usage counts the children the process waited for (the plot child) with it
    return Sample(wall, inside, lab, usage.ru_maxrss / 1024.0,  # Linux: KiB
                  usage.ru_utime + usage.ru_stime)


def cost(tree: Tree, module: str, call: str) -> str:
    """``module.call`` from the tree's bench/, run in a fresh process; NA if absent."""
    code = (f"import sys; sys.path.insert(0, 'bench')\n"
            f"try:\n    from {module} import {call.split('(')[0]}\n"
            f"except ImportError:\n    print('NA'); raise SystemExit(0)\n"
            f"print(repr({call}))")
    env = child_env(tree)
    r = subprocess.run([sys.executable, "-c", code], cwd=tree.root, env=env,
                       capture_output=True, text=True)
    if r.returncode != 0:
        return f"failed: {(r.stderr.strip().splitlines() or [''])[-1]}"
    last = (r.stdout.strip().splitlines() or ["NA"])[-1]
    return NA if last == "NA" else last


@contextlib.contextmanager
def checked_out(rev: str) -> Iterator[Path]:
    """REV in a temporary detached git worktree of this repository, removed afterwards."""
    tmp = Path(tempfile.mkdtemp(prefix="speed-rev-"))
    where = tmp / "tree"
    subprocess.run(["git", "-C", str(HERE), "worktree", "add", "--detach", "--quiet",
                    str(where), rev], check=True)
    try:
        yield where
    finally:
        subprocess.run(["git", "-C", str(HERE), "worktree", "remove", "--force", str(where)],
                       check=False)
        with contextlib.suppress(OSError):
            tmp.rmdir()


def _med(xs: list[float | None]) -> float | None:
    ys = [x for x in xs if x is not None]
    return statistics.median(ys) if ys else None


def _f(x: float | None, fmt: str = ".2f") -> str:
    return "-" if x is None else format(x, fmt)


def summary(s: list[Sample]) -> dict[str, float | None]:
    """min and median wall, median inside, lab hours, lab s per wall s, peak MB, median CPU."""
    wall = [x.wall for x in s]
    med = statistics.median(wall)
    lab = _med([x.lab_s for x in s])
    return {"min": min(wall), "median": med, "inside": _med([x.inside for x in s]),
            "lab_h": None if lab is None else lab / 3600.0,
            "lab_per_wall": None if lab is None else lab / med,
            "peak_mb": max(x.peak_mb for x in s), "cpu": _med([x.cpu for x in s])}


def report(trees: list[Tree], names: list[str], repeat: int) -> None:
    """The table: one row per command and tree, then the ratios first tree / last tree."""
    print(f"whole process, {repeat} runs each, interleaved; load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}, {os.cpu_count()} CPUs")
    head = (f"{'command':<12} {'tree':<10} {'min s':>7} {'median s':>9} {'inside s':>9} "
            f"{'lab h':>7} {'lab s/wall s':>13} {'peak MB':>8} {'cpu s':>7}")
    print(head)
    print("-" * len(head))
    for name in names:
        for t in trees:
            m = summary(t.samples[name])
            print(f"{name:<12} {t.label:<10} {_f(m['min']):>7} {_f(m['median']):>9} "
                  f"{_f(m['inside']):>9} {_f(m['lab_h']):>7} {_f(m['lab_per_wall'], '.0f'):>13} "
                  f"{_f(m['peak_mb'], '.0f'):>8} {_f(m['cpu']):>7}")
        if len(trees) == 2:
            a, b = (summary(t.samples[name]) for t in trees)
            ratio = {k: (a[k] / b[k] if a[k] and b[k] else None)  # type: ignore[operator]
                     for k in ("min", "median", "inside", "peak_mb", "cpu")}
            print(f"{name:<12} {'ratio':<10} {_f(ratio['min']):>7} {_f(ratio['median']):>9} "
                  f"{_f(ratio['inside']):>9} {'':>7} {'':>13} {_f(ratio['peak_mb']):>8} "
                  f"{_f(ratio['cpu']):>7}")
    if any(t.costs for t in trees):
        print()
        for t in trees:
            for k, v in t.costs.items():
                print(f"{t.label:<10} {k}: {v}")
    print(f"\ncpu s: median user + system time of the process and the children it reaped "
          f"(the plot child, where the run reaps it before it exits; a day leaves it to a "
          f"thread that the exit may overtake, so its child is then not counted); on "
          f"{os.cpu_count()} CPUs each run's wall is at least its own cpu s / {os.cpu_count()}")
    if len(trees) == 2:
        print(f"\nratio: {trees[0].label} / {trees[1].label} (above 1: {trees[1].label} is "
              "faster)")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("--repeat", type=int, default=5, help="runs of each command per tree")
    ap.add_argument("--commands", default=",".join(COMMANDS),
                    help=f"comma-separated, of {', '.join(COMMANDS)}")
    ap.add_argument("--against", metavar="REV", help="also run REV (a temporary worktree), "
                    "interleaved, and print the ratios REV / this tree")
    ap.add_argument("--tree", type=Path, default=HERE, help="the tree under test "
                    "(default: the one holding this script)")
    ap.add_argument("--no-costs", action="store_true", help="skip the IEU stream and gate "
                    "cost figures")
    a = ap.parse_args(argv)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # still remove the worktree
    names = [n.strip() for n in a.commands.split(",") if n.strip()]
    bad = [n for n in names if n not in COMMANDS]
    if bad:
        ap.error(f"--commands: unknown {', '.join(bad)}: {', '.join(COMMANDS)}")
    if a.repeat < 1:
        ap.error(f"--repeat must be 1 or more, got {a.repeat}")
    with contextlib.ExitStack() as stack:
        trees = [Tree("this", a.tree.resolve())]
        if a.against:
            trees.insert(0, Tree(a.against[:10], stack.enter_context(checked_out(a.against))))
        scratch = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="speed-")))
        for t in trees:
            t.samples = {n: [] for n in names}
            t.cli = cli_module(t.root)
            byte_compile(t)
        for i in range(a.repeat):
            for name in names:
                order = trees if i % 2 == 0 else trees[::-1]
                for t in order:
                    t.samples[name].append(run_once(t, name, scratch, i))
            print(f"repeat {i + 1}/{a.repeat} done", file=sys.stderr, flush=True)
        if not a.no_costs:
            for t in trees:
                t.costs["IEU cost per 0.1 s sample, 4 h static stream"] = cost(
                    t, "ieu_stream", "ieu_cost_per_sample(4.0)")
                t.costs["counter gate cost ratio 30 min / 1 s"] = cost(
                    t, "gate_cost", "gate_cost_ratio()")
        report(trees, names, a.repeat)


if __name__ == "__main__":
    main()
