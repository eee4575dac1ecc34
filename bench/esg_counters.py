"""Two counters against three (docs/esg-options.md): over seeds, the calibration's
simulated time, step 4's time, the equal-ratio spread and the true readout rms.

    python bench/esg_counters.py [n_seeds]
"""

from __future__ import annotations

import json
import tempfile
from dataclasses import replace
from pathlib import Path

from _args import count, parser

from laboratory.esg.calibration import run_esg_calibration
from sim.esg import EsgParams


def one(seed: int, counters: int) -> dict:
    """One calibration's figures."""
    with tempfile.TemporaryDirectory() as d:
        res = run_esg_calibration(seed, Path(d), params=replace(EsgParams(), counters=counters),
                                  with_study=False)
        prev, step4 = 0.0, 0.0
        for line in (Path(d) / "journal.jsonl").read_text().splitlines():
            j = json.loads(line)
            if j.get("kind") != "step":
                continue
            if j["step"] in ("4a", "4b"):
                step4 += j["t_sim"] - prev
            prev = j["t_sim"]
    return {"sim_s": res["sim_seconds"], "step4_s": step4,
            **{s["name"]: s["true_readout_rms_arcsec"] for s in res["schedules"]}}


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__)
    ap.add_argument("n", metavar="n_seeds", nargs="?", type=count, default=4,
                    help="seeds 1..n_seeds (default 4)")
    a = ap.parse_args(argv)
    n = a.n
    for counters in (2, 3):
        rows = [one(seed, counters) for seed in range(1, n + 1)]
        mean = {k: sum(r[k] for r in rows) / n for k in rows[0]}
        print(f"counters {counters}: " + ", ".join(f"{k} {v:.1f}" for k, v in mean.items()))


if __name__ == "__main__":
    main()
