"""How often do the plausibility checks stop, re-read or relevel a fault-free day?

    python bench/false_stops.py [N] [FIRST_SEED] [--jobs J]

Runs N fault-free calibration days (alignments included; default 40 from seed 2000) and
prints: days stopped (with the stop), re-reads, relevellings and IEU retakes, and per
check family the largest |z| seen against its limit (procedures.isu.plausibility.K_READING
for readings, K_RESULT for results) with a normal-tail estimate of the false-stop rate per
day. Every number comes from the days' journals.
"""

from __future__ import annotations

import json
import math
import sys
import tempfile
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from _args import count, parser

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


READING_CHECKS: dict[str, list[float]] = defaultdict(list)


def instrument() -> None:
    """Record the largest deviation (sigma) each reading check sees, by wrapping them
    (once per worker process)."""
    import numpy as np

    from procedures.isu import common, plausibility
    from procedures.isu.alignment import sampling

    if getattr(plausibility, "_bench_wrapped", False):
        return
    plausibility._bench_wrapped = True  # type: ignore[attr-defined]
    dev0, samp0, lev0 = (plausibility.deviations, sampling.sample_deviations,
                         common.level_check_z)

    def deviations(values, sigma):
        d = dev0(values, sigma)
        READING_CHECKS["readings vs their median (levels, autocollimators)"].append(
            float(np.max(d)))
        return d

    def sample_deviations(counts, noise):
        d, med = samp0(counts, noise)
        READING_CHECKS["IEU sample counts vs neighbours"].append(float(np.max(d)))
        return d, med

    def level_check_z(check, applied, sigma):
        z = lev0(check, applied, sigma)
        READING_CHECKS["levelling confirmation"].append(z)
        return z

    plausibility.deviations = deviations
    sampling.sample_deviations = sample_deviations
    common.level_check_z = level_check_z


def one(seed: int) -> dict:
    from rich.console import Console

    from laboratory.isu.day import DayRequest, run_day
    from procedures.runner import ProcedureError
    from station.config.isu import load_config

    instrument()
    READING_CHECKS.clear()
    with tempfile.TemporaryDirectory() as d:
        stop = None
        try:
            run_day(DayRequest(load_config(seed=seed), Path(d), quiet=True),
                    Console(quiet=True))
        except ProcedureError as e:
            stop = str(e)
        recs = [json.loads(x) for x in (Path(d) / "journal.jsonl").read_text().splitlines()]
    return {"seed": seed, "stop": stop, "readings": dict(READING_CHECKS), **scan(recs)}


def scan(recs: list[dict]) -> dict:
    """z of every judged check, and every re-read, relevelling and retake, from a journal."""
    z: dict[str, list[float]] = defaultdict(list)
    events: dict[str, int] = defaultdict(int)

    def walk(x, chart: str) -> None:
        if isinstance(x, dict):
            for k, v in x.items():
                if k == "rereads":
                    events["re-reads"] += len(v)
                elif k == "relevelled":
                    events["relevellings"] += len(v)
                elif k == "retakes":
                    events["IEU retakes"] += len(v)
                elif k == "residual_z":
                    z["calibration residuals (II-15)"] += [abs(float(t)) for t in v.values()]
                elif k == "string_sum_z":
                    z["calibration string sums (II-15)"] += [abs(float(t)) for t in v.values()]
                elif k == "special_z":
                    for name, zs in v.items():
                        z[f"calibration {name.split()[0]} speeds/pairs (II-15)"] += [
                            abs(float(t)) for t in zs]
                elif k == "checks":
                    for name, c in v.items():
                        items = c.items() if "z" not in c else [(name, c)]
                        for n2, cc in items:
                            if isinstance(cc, dict) and "z" in cc:
                                z[f"{chart} {n2}"].append(abs(float(cc["z"])))
                else:
                    walk(v, chart)
        elif isinstance(x, list):
            for v in x:
                walk(v, chart)

    for r in recs:
        if r.get("kind") == "step":
            walk(r.get("reading"), f"Chart {r['chart']}")
    return {"z": dict(z), "events": dict(events)}


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__)
    ap.add_argument("n", metavar="N", nargs="?", type=count, default=40,
                    help="fault-free days (default 40)")
    ap.add_argument("first", metavar="FIRST_SEED", nargs="?", type=int, default=2000,
                    help="the first day's seed (default 2000)")
    ap.add_argument("--jobs", metavar="J", type=count, default=2,
                    help="days run at once (default 2)")
    args = ap.parse_args(argv)
    from procedures.isu.alignment.checks import K_RESULT
    from procedures.isu.calibration.checks import K_RESULT as K_CAL

    with ProcessPoolExecutor(max_workers=args.jobs) as ex:
        days = list(ex.map(one, range(args.first, args.first + args.n)))
    stops = [d for d in days if d["stop"]]
    print(f"{len(days)} fault-free days, seeds {args.first}..{args.first + args.n - 1}: "
          f"{len(stops)} stopped")
    for d in stops:
        print(f"  seed {d['seed']}: {d['stop'][:300]}")
    ev: dict[str, int] = defaultdict(int)
    for d in days:
        for k, v in d["events"].items():
            ev[k] += v
    print("events: " + (", ".join(f"{k} {v}" for k, v in sorted(ev.items())) or "none"))
    fam: dict[str, list[float]] = defaultdict(list)
    per_day: dict[str, float] = defaultdict(float)
    for d in days:
        for k, v in d["z"].items():
            fam[k] += v
            per_day[k] += len(v)
    print(f"{'check':55} {'n':>6} {'rms z':>6} {'max|z|':>7} {'limit':>5} {'P(stop)/day':>11}")
    total = 0.0
    for k in sorted(fam):
        v = fam[k]
        lim = K_CAL if k.startswith("calibration") else K_RESULT
        rms = math.sqrt(sum(x * x for x in v) / len(v))
        # normal tail at the limit, scaled by the observed rms (an honest sigma gives rms 1)
        p = math.erfc(lim / max(rms, 1e-9) / math.sqrt(2.0)) * per_day[k] / len(days)
        total += p
        print(f"{k:55} {len(v):6d} {rms:6.2f} {max(v):7.2f} {lim:5.1f} {p:11.2e}")
    print(f"estimated false-stop rate of the result checks: {total:.2e} per day")
    rd: dict[str, list[float]] = defaultdict(list)
    for d in days:
        for k, v in d["readings"].items():
            rd[k] += v
    from procedures.isu.plausibility import K_READING

    print(f"reading checks (limit {K_READING:g} sigma): largest deviation per check")
    for k, v in sorted(rd.items()):
        print(f"  {k:55} {len(v):6d} checks, max {max(v):.2f} sigma")


if __name__ == "__main__":
    main()
