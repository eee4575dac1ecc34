"""How far a rehearsal drifts from its virtual twin: the time quantization of real time.

Serves the rack at ``speed`` in its own process, runs the survey and positions 7 and 8
through ``station day --links`` as a subprocess, runs the virtual twin (same seed, begun
at the simulated instant the rehearsal began) and prints: wall time, commands applied by
the server, how much later the rehearsal's steps ran (largest, and as a fraction of the
elapsed simulated time), the largest differences of the compared quantities, and the
verdict of station.hil.twin.compare_rehearsal.

    python bench/hil_twin.py [speed] [seed]   (default 500x, seed 11)
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _args import parser, positive

from laboratory.isu.day import DayRequest, run_day
from station.config.isu import load_config
from station.hil import link_map
from station.hil.twin import compare_rehearsal

DAY = ["--only", "II-11", "--only", "II-13", "--positions", "7", "--positions", "8"]


def _sheet(d: Path, name: str) -> dict:
    return json.loads((d / "sheets" / f"{name}.json").read_text())


def main(argv: list[str]) -> None:
    ap = parser(__doc__)
    ap.add_argument("speed", nargs="?", type=positive, default=500.0,
                    help="the served rack's speed, simulated s per wall s (default 500)")
    ap.add_argument("seed", nargs="?", type=int, default=11,
                    help="the laboratory's seed (default 11)")
    a = ap.parse_args(argv)
    speed, seed = a.speed, a.seed
    with tempfile.TemporaryDirectory() as d:
        base = Path(d)
        links = base / "links"
        log = open(base / "server.out", "w")
        server = subprocess.Popen(
            [sys.executable, "-m", "laboratory.cli", "serve", "--seed", str(seed), "--speed",
             str(speed), "--links", str(links)], stdout=log, stderr=subprocess.STDOUT)
        try:
            while not (links / link_map.FILENAME).exists():
                if server.poll() is not None:
                    raise SystemExit((base / "server.out").read_text())
                time.sleep(0.05)
            w0 = time.perf_counter()
            day = subprocess.run(
                [sys.executable, "-m", "laboratory.cli", "day", "--links", str(links), "--seed",
                 str(seed), *DAY, "--out", str(base / "run"), "--quiet"],
                capture_output=True, text=True)
            wall = time.perf_counter() - w0
        finally:
            server.send_signal(signal.SIGTERM)
            server.wait(15)
            log.close()
        if day.returncode:
            raise SystemExit(day.stdout + day.stderr)
        run = base / "run"
        journal = [json.loads(x) for x in (run / "journal.jsonl").read_text().splitlines()]
        t0 = next(r for r in journal if r.get("event") == "start")["t_sim"]
        twin = base / "twin"
        run_day(DayRequest(load_config(seed=seed), twin, quiet=True, only=("II-11", "II-13"),
                           positions=(7, 8), start_s=t0))
        late, frac = [], []
        for name in sorted(p.stem for p in (run / "sheets").glob("check_*.json")):
            for x, y in zip(_sheet(run, name)["steps"], _sheet(twin, name)["steps"],
                            strict=True):
                late.append(x["t_sim"] - y["t_sim"])
                if y["t_sim"] - t0 > 60:
                    frac.append((x["t_sim"] - y["t_sim"]) / (y["t_sim"] - t0))
        oa = _sheet(run, "counter_outputs")["outputs"]
        ob = _sheet(twin, "counter_outputs")["outputs"]
        gyro = max(abs(int(oa[r][c]) - int(ob[r][c])) for r in oa if r.startswith("gyro")
                   for c in oa[r])
        accel = max(abs(int(oa[r][c]) - int(ob[r][c])) / int(ob[r][c]) for r in oa
                    if r.startswith("accel") for c in oa[r])
        ta, tb = _sheet(run, "survey_results")["t_bi"], _sheet(twin, "survey_results")["t_bi"]
        tbi = max(abs(x - y) for ra, rb in zip(ta, tb, strict=True)
                  for x, y in zip(ra, rb, strict=True))
        elapsed = journal[-1].get("sim_seconds", 0.0) - t0
        print(f"speed {speed:g}x, seed {seed}: {elapsed / 3600:.2f} h simulated in "
              f"{wall:.1f} s wall")
        print(f"  steps later than the twin: max {max(late):.1f} s, min {min(late):+.2f} s; "
              f"max {100 * max(frac):.1f} % of the elapsed time")
        print(f"  gyro net pulses max |diff| {gyro}; accelerometer clock counts max "
              f"relative diff {accel:.2e}; T^BI max diff {tbi:.2e}")
        problems = compare_rehearsal(run, twin)
        print(f"  compare_rehearsal: {'equal within tolerances' if not problems else problems}")
        print("  server:", (base / "server.out").read_text().strip().splitlines()[-1])


if __name__ == "__main__":
    main(sys.argv[1:])
