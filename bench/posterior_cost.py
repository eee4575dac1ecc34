"""Wall time of the level alignment's posterior (procedures.isu.alignment.estimation) against K.

Prints, per (K, dt), the median of 5 evaluations of ``posterior_level`` on the default
noise specification. The figure that used to be a test assertion (K = 300 under 1 s) lives
here: tests hold no wall-clock assertion.
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from _args import parser  # noqa: E402
from test_alignment_estimator import default_params  # noqa: E402

from procedures.isu.alignment.estimation import posterior_level  # noqa: E402


def main(argv: list[str] | None = None) -> None:
    parser(__doc__).parse_args(argv)
    for K, dt in ((10, 1.0), (60, 1.0), (120, 1.0), (300, 1.0), (600, 1.0)):
        params = default_params(K, dt)
        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            posterior_level(params)
            times.append(time.perf_counter() - t0)
        print(f"K={K:4d} dt={dt:3.1f} s  posterior {statistics.median(times) * 1e3:8.1f} ms")


if __name__ == "__main__":
    main()
