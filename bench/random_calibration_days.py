"""Calibration data of random admissible laboratories (tests/random_labs.py), one JSON file
per seed (CalibrationData, NoiseSpec, truth), for bench/all_positions_stats.py.

    PYTHONPATH=. nice -n 10 python bench/random_calibration_days.py OUTDIR SEED...
    (CHARTS=II7 in the environment: the II-7 speed series too)
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from _args import parser  # noqa: E402
from random_labs import POSITION_CHARTS, calibration_day, random_lab  # noqa: E402


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__,
                                 epilog="CHARTS=II7 in the environment: the II-7 speed "
                                 "series too.")
    ap.add_argument("out", metavar="OUTDIR", type=Path,
                    help="where the lab<SEED>.json files go (made if missing)")
    ap.add_argument("seeds", metavar="SEED", type=int, nargs="+",
                    help="the random laboratories' seeds")
    a = ap.parse_args(argv)
    out = a.out
    out.mkdir(parents=True, exist_ok=True)
    for seed in a.seeds:
        charts = (*POSITION_CHARTS, "II-7") if "II7" in os.environ.get("CHARTS", "") else \
            POSITION_CHARTS
        cd, noise, truth, series = calibration_day(random_lab(seed), charts)
        doc = {"seed": seed, "data": cd, "noise": noise, "truth": truth, "nonlinearity": series}
        (out / f"lab{seed}.json").write_text(json.dumps(doc))
        print(seed, flush=True)


if __name__ == "__main__":
    main()
