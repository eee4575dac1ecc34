"""Both estimators against the truth and the Cramer-Rao bound over random labs written by
bench/random_calibration_days.py: per constant the rms of error/sigma (closed forms and
all positions), the median sigma ratio closed/all-positions, all-positions/CRB (at truth),
and the observed rms error ratio. The II-7 speed series are fitted when a lab file has them.

    PYTHONPATH=. nice -n 10 python bench/all_positions_stats.py LABDIR
"""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

import numpy as np
from _args import parser

from procedures.isu.calibration import CalibrationData, NoiseSpec
from procedures.isu.calibration.all_positions import cramer_rao, fit
from procedures.isu.calibration.compute import constants_covariance


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__)
    ap.add_argument("labdir", metavar="LABDIR", type=Path,
                    help="the lab*.json files of bench/random_calibration_days.py")
    a = ap.parse_args(argv)
    if not a.labdir.is_dir():
        ap.error(f"LABDIR {a.labdir} is not a directory")
    stats: dict[tuple[str, str], list[tuple[float, ...]]] = defaultdict(list)
    files = sorted(a.labdir.glob("lab*.json"))
    worst = 0.0
    for p in files:
        doc = json.loads(p.read_text())
        data = CalibrationData.model_validate(doc["data"])
        noise = NoiseSpec.model_validate(doc["noise"])
        truth = {tuple(k.split("|")): v for k, v in doc["truth"].items()}
        series = {int(k): v for k, v in doc.get("nonlinearity", {}).items()}
        est, rows, cov = constants_covariance(data, noise)
        f = fit(data, noise, closed=est, series=series)
        crows, crb = cramer_rao(data, truth, noise, closed=est, series=series)
        for r in f.rows:
            s = f.sigma(r)
            e = f.estimates[r] - truth[r]
            bound = float(np.sqrt(crb[crows.index(r), crows.index(r)]))
            if r in rows:
                sc = float(np.sqrt(cov[rows.index(r), rows.index(r)]))
                ec = float(est[r]) - truth[r]  # type: ignore[arg-type]
            else:
                sc, ec = float("nan"), float("nan")
            worst = max(worst, abs(e / s))
            stats[r].append((e / s, ec / sc, sc / s, s / bound, e, ec))
    print(f"{len(files)} labs; worst |all-positions error|/sigma {worst:.2f}")
    print(f"{'row':18s} {'rms z ap':>8s} {'rms z cf':>8s} {'cf/ap':>6s} {'min':>5s} "
          f"{'ap/crb':>6s} {'max':>6s} {'obs cf/ap':>9s}")
    for r, v in stats.items():
        a = np.array(v)
        obs = np.sqrt(np.nanmean(a[:, 5] ** 2) / np.mean(a[:, 4] ** 2))
        print(f"{r[0] + ' ' + r[1]:18s} {np.sqrt(np.mean(a[:, 0] ** 2)):8.2f} "
              f"{np.sqrt(np.nanmean(a[:, 1] ** 2)):8.2f} {np.nanmedian(a[:, 2]):6.2f} "
              f"{np.nanmin(a[:, 2]):5.2f} {np.median(a[:, 3]):6.3f} {np.max(a[:, 3]):6.3f} "
              f"{obs:9.2f}")


if __name__ == "__main__":
    main()
