"""Are the predicted standard errors honest? A Monte Carlo of whole calibration days.

A thin wrapper over the campaign bench/campaigns/day.toml (`station campaign` on the
machine's cores): per constant the observed rms error over the predicted sigma with its
99 % chi-square interval and the largest |error|/sigma; the rows stay as Parquet.

    python bench/calibration_mc.py [N] [first_seed] [OUT]   (N days, default 30)
"""

from __future__ import annotations

import sys

from _campaign import run_bench

if __name__ == "__main__":
    run_bench("day", sys.argv)
