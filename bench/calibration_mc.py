"""Are the predicted standard errors honest? A Monte Carlo of whole calibration days.

Runs `station day` on N seeds (default 30; two processes), and for every constant prints the
observed scatter of (estimate - truth), the mean predicted sigma, their ratio (acceptance:
0.7 to 1.4), the largest |error|/sigma, and the mean wall time of a day.

    python bench/calibration_mc.py [N] [first_seed]
"""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path


def one(seed: int) -> dict:
    from rich.console import Console

    from laboratory.isu.day import DayRequest, run_day
    from station.config.isu import load_config

    with tempfile.TemporaryDirectory() as d:
        res = run_day(DayRequest(load_config(seed=seed), Path(d), quiet=True),
                      Console(quiet=True))
    return res


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 30
    first = int(sys.argv[2]) if len(sys.argv) > 2 else 1000
    with ProcessPoolExecutor(max_workers=2) as ex:
        runs = list(ex.map(one, range(first, first + n)))
    by_key: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for r in runs:
        for row in r["calibration"]:
            if row["estimate"] is None or row["sigma"] is None:
                continue
            by_key.setdefault((row["instrument"], row["parameter"]), []).append(
                (row["error"], row["sigma"])
            )
    print(f"{n} seeds from {first}; mean wall time of a day "
          f"{statistics.mean(r['wall_seconds'] for r in runs):.2f} s, "
          f"simulated {statistics.mean(r['sim_seconds'] for r in runs) / 3600:.2f} h")
    print(f"{'instrument':10} {'parameter':9} {'rms error':>12} {'mean sigma':>12} "
          f"{'ratio':>6} {'max|z|':>7}")
    bad = []
    for (inst, par), v in sorted(by_key.items()):
        errs = [e for e, _ in v]
        sig = statistics.mean(s for _, s in v)
        rms = (sum(e * e for e in errs) / len(errs)) ** 0.5
        ratio = rms / sig if sig > 0 else float("inf")
        zmax = max(abs(e) / s for e, s in v)
        flag = "" if 0.7 <= ratio <= 1.4 else "  <-- outside 0.7-1.4"
        if flag:
            bad.append((inst, par, ratio))
        print(f"{inst:10} {par:9} {rms:12.4g} {sig:12.4g} {ratio:6.2f} {zmax:7.2f}{flag}")
    print(f"{len(by_key) - len(bad)} of {len(by_key)} constants within 0.7-1.4")
    Path("bench/calibration_mc.json").write_text(json.dumps(
        {f"{i}:{p}": v for (i, p), v in by_key.items()}, indent=0))


if __name__ == "__main__":
    main()
