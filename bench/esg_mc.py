"""Monte Carlo over seeds of the ESG calibration: is the predicted assignment error honest?

A thin wrapper over the campaign bench/campaigns/esg.toml: per schedule the observed
assignment rms against the predicted one, the readout and calibration rms against the true.

    python bench/esg_mc.py [N] [campaign_seed] [OUT]   (default 20 calibrations)
"""

from __future__ import annotations

import sys

from _campaign import run_bench

if __name__ == "__main__":
    run_bench("esg", sys.argv)
