"""Are the closed forms' and the alignments' predicted sigmas honest in any laboratory (issue 19)?

Runs whole days (calibration and the three alignments) on random admissible laboratories
(tests/random_lab.py) and prints, per constant and per alignment axis, the mean and rms of
error / predicted sigma over the seeds, with the largest |z|; ``--json FILE`` keeps the per-day
z for a before/after comparison (run the same seeds against another tree).

    nice python bench/honest_sigmas.py [N] [first_seed] [--fixed-isu] [--noise F] [--json F]
                                       [--workers W]
"""

from __future__ import annotations

import json
import math
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from _args import count, parser
from scipy.stats import chi2

ROOT = Path(__file__).resolve().parents[1]


def one(job: tuple[int, bool, float | None]) -> dict:
    seed, redraw, noise = job
    sys.path.insert(0, str(ROOT / "tests"))
    from random_lab import random_station
    from rich.console import Console

    from laboratory.isu.day import DayRequest, run_day

    cfg = random_station(seed, redraw_isu=redraw, noise=noise)
    with tempfile.TemporaryDirectory() as d:
        try:
            res = run_day(DayRequest(cfg, Path(d) / "day", quiet=True), Console(quiet=True))
        except Exception as e:  # a day that stops: reported, not pooled
            return {"seed": seed, "lat": cfg.site.latitude_deg, "z": {}, "stopped": str(e)}
    z: dict[str, float] = {}
    for r in res["calibration"]:
        if r.get("sigma") and r.get("error") is not None:
            z[f"{r['instrument']} {r['parameter']}"] = r["error"] / r["sigma"]
    for a in res["alignment"]:
        for axis, x in zip(("E", "N", "az"), a["error_over_sigma"], strict=True):
            z[f"{a['method']}/{a['estimator']} {axis}"] = x
    return {"seed": seed, "lat": cfg.site.latitude_deg, "z": z}


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__)
    ap.add_argument("n", metavar="N", type=count, nargs="?", default=20,
                    help="days, one random laboratory each (default 20)")
    ap.add_argument("first", metavar="first_seed", type=int, nargs="?", default=1,
                    help="the first laboratory's seed (default 1)")
    ap.add_argument("--fixed-isu", action="store_true",
                    help="keep the default ISU's coefficients (redraw the rest)")
    ap.add_argument("--noise", metavar="F", type=float, default=None,
                    help="every noise factor (gyro, accelerometer, pier) fixed to F "
                    "(default: drawn)")
    ap.add_argument("--json", metavar="F", type=Path, default=None,
                    help="write the per-day z here")
    ap.add_argument("--workers", metavar="W", type=count, default=2,
                    help="days run at once (default 2)")
    a = ap.parse_args(argv)
    jobs = [(s, not a.fixed_isu, a.noise) for s in range(a.first, a.first + a.n)]
    with ProcessPoolExecutor(a.workers) as ex:
        days = list(ex.map(one, jobs))
    if a.json:
        a.json.write_text(json.dumps(days))
    for d in days:
        if "stopped" in d:
            print(f"seed {d['seed']} stopped: {d['stopped'][:200]}")
    names = sorted({k for d in days for k in d["z"]})
    print(f"{len(days)} days; name: mean z, rms z, max |z| (rms 99 % interval for n)")
    for k in names:
        zs = [d["z"][k] for d in days if k in d["z"]]
        n = len(zs)
        mean = sum(zs) / n
        rms = math.sqrt(sum(x * x for x in zs) / n)
        lo, hi = (math.sqrt(chi2.ppf(q, n) / n) for q in (0.005, 0.995))
        flag = "" if lo <= rms <= hi and abs(mean) < 2.576 / math.sqrt(n) else "  <--"
        print(f"{k:34s} {mean:+6.2f} {rms:5.2f} {max(abs(x) for x in zs):5.2f}{flag}")


if __name__ == "__main__":
    main()
