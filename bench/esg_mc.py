"""Monte Carlo over seeds of the ESG calibration: is the predicted assignment error honest?

For each seed: the rms over points of (assigned - true colatitude) against the rms of the
predicted sigmas, the readout errors (measured and true) of both schedules, wall time.
Usage: python bench/esg_mc.py [N] [FIRST_SEED]
"""

from __future__ import annotations

import math
import statistics
import sys
import tempfile
import time

from laboratory.esg.calibration import run_esg_calibration


def main(n: int = 20, first: int = 100) -> None:
    obs, pred, wall = [], [], []
    rd = {"5deg": ([], []), "1-2-5deg": ([], [])}
    for seed in range(first, first + n):
        with tempfile.TemporaryDirectory() as d:
            t = time.perf_counter()
            res = run_esg_calibration(seed, d, with_study=False)
            wall.append(time.perf_counter() - t)
        s0 = res["schedules"][0]
        obs.append(s0["assignment_rms_arcsec"])
        pred.append(s0["predicted_assignment_rms_arcsec"])
        for s in res["schedules"]:
            rd[s["name"]][0].append(s["readout_rms_arcsec"])
            rd[s["name"]][1].append(s["true_readout_rms_arcsec"])
        print(f"seed {seed}: assignment {obs[-1]:5.2f} predicted {pred[-1]:5.2f} arcsec; "
              + "; ".join(f"{k} readout {v[0][-1]:5.2f} true {v[1][-1]:5.2f}"
                          for k, v in rd.items()) + f"; {wall[-1]:.2f} s", flush=True)
    q = math.sqrt(sum(x * x for x in obs) / n) / math.sqrt(sum(x * x for x in pred) / n)
    print(f"\n{n} seeds: observed / predicted assignment rms = {q:.2f}")
    for k, (m, tr) in rd.items():
        print(f"{k}: readout rms mean {statistics.mean(m):.2f} (max {max(m):.2f}), "
              f"true mean {statistics.mean(tr):.2f} (max {max(tr):.2f}) arcsec")
    print(f"wall per calibration: mean {statistics.mean(wall):.2f} s, max {max(wall):.2f} s")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
