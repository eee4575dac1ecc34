"""Are the measured instabilities (delta, Delta) within their sampling distributions?

For each seed the whole CIGTF test runs twice: as measured, and with the DVM's current noise
switched off, which leaves each run's true theta (drift walk, fixture repeatability). The
simulated instability is the spread of those true thetas; with the runs' own noise sigma it
predicts E[delta^2] = s_true^2 + mean(sigma_run^2). delta^2 / prediction should follow
chi^2(n-1)/(n-1): the script prints its mean (1 expected) and the fraction of seeds inside
the central 95 % interval, for both phases, and the phase theta's |error| / sigma.

    python bench/gyrocompass_mc.py [N] [first_seed]

Kept as a script for its paired runs, which a campaign's independent tasks do not express;
the per-seed errors against the predicted sigma are the campaign bench/campaigns/gyrocompass.toml.
"""

from __future__ import annotations

import statistics
import tempfile
from dataclasses import replace
from pathlib import Path

from _args import parser, seeds
from scipy import stats

from laboratory.cigtf.gyrocompassing import run_gyrocompass_test
from sim.cigtf.world import CigtfParams


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__)
    seeds(ap, 30, 100)
    a = ap.parse_args(argv)
    n, first = a.n, a.first
    quiet = replace(CigtfParams(), current_noise_ma=0.0)
    ratios: dict[str, list[float]] = {"operating": [], "shutdown": []}
    zs: list[float] = []
    for seed in range(first, first + n):
        with tempfile.TemporaryDirectory() as a, tempfile.TemporaryDirectory() as b:
            res = run_gyrocompass_test(seed, Path(a))
            true = run_gyrocompass_test(seed, Path(b), params=quiet)
        truth = res["truth"]["theta_arcsec"]
        for ph, key in (("operating", "delta_arcsec"), ("shutdown", "Delta_arcsec")):
            th0 = [r["theta_arcsec"] for r in true["runs"] if r["phase"] == ph]
            sig = [r["sigma_arcsec"] for r in res["runs"] if r["phase"] == ph]
            pred = statistics.variance(th0) + statistics.mean(s * s for s in sig)
            ratios[ph].append(res[key] ** 2 / pred)
        for p in res["phases"]:
            zs.append((p["theta_arcsec"] - truth) / p["sigma_arcsec"])
    print(f"{n} seeds from {first}")
    for ph, r in ratios.items():
        k = 24 if ph == "operating" else 9
        lo, hi = stats.chi2.ppf([0.025, 0.975], k) / k
        inside = sum(lo <= x <= hi for x in r) / len(r)
        name = "delta" if ph == "operating" else "Delta"
        print(f"{name:5} ({ph}): mean of {name}^2/predicted {statistics.mean(r):.3f} "
              f"(1 expected), inside the 95 % chi^2({k}) interval: {100 * inside:.0f} %")
    print(f"phase theta: rms (theta - truth)/sigma {statistics.mean(z * z for z in zs) ** .5:.2f},"
          f" max |.| {max(abs(z) for z in zs):.2f} over {len(zs)} phases")


if __name__ == "__main__":
    main()
