"""Monte Carlo over seeds of the ESG calibration: is the predicted assignment error honest?

A thin wrapper over the campaign bench/campaigns/esg.toml: per schedule the observed
assignment rms against the predicted one, the readout and calibration rms against the true.

    python bench/esg_mc.py [N] [SEED] [OUT]   (N calibrations, default 20; campaign seed 100)
"""

from __future__ import annotations

import sys

from _campaign import run_bench


def main(argv: list[str] | None = None) -> None:
    """``argv``: the arguments after the program's name (default ``sys.argv[1:]``)."""
    run_bench("esg", [sys.argv[0], *(sys.argv[1:] if argv is None else argv)],
              __doc__.split("\n\n")[0])


if __name__ == "__main__":
    main()
