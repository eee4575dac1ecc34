"""Are the predicted standard errors honest? A Monte Carlo of whole calibration days.

A thin wrapper over the campaign bench/campaigns/day.toml (`station campaign` on the
machine's cores): per constant the observed rms error over the predicted sigma with its
99 % chi-square interval and the largest |error|/sigma; the rows stay as Parquet.

    python bench/calibration_mc.py [N] [SEED] [OUT]   (N days, default 30; campaign seed 1000)
"""

from __future__ import annotations

import sys

from _campaign import run_bench


def main(argv: list[str] | None = None) -> None:
    """``argv``: the arguments after the program's name (default ``sys.argv[1:]``)."""
    run_bench("day", [sys.argv[0], *(sys.argv[1:] if argv is None else argv)],
              __doc__.split("\n\n")[0])


if __name__ == "__main__":
    main()
