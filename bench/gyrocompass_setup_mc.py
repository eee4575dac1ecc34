"""Does the pre-test set-up (report 001, section 4.1) leave b, c and a + d within their
stated sigmas of the simulator's truth?

For each seed the set-up (procedures/cigtf/setup.py) runs on a fresh CIGTF rack; the
script prints, per quantity, the rms and the largest |estimate - truth| / sigma (rms 1
expected), the rms of the true residuals, and the rounds the levels and the azimuth took.

    python bench/gyrocompass_setup_mc.py [N] [first_seed]
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from _args import parser, seeds

from procedures.cigtf.setup import pretest_setup
from procedures.journal import Journal
from procedures.runner import Run
from sim.units import to_arcsec
from station.racks.cigtf import CigtfRack, open_cigtf_drivers


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__)
    seeds(ap, 30, 100)
    a = ap.parse_args(argv)
    n, first = a.n, a.first
    z, true, rounds = [], [], []
    with tempfile.TemporaryDirectory() as d:
        for seed in range(first, first + n):
            rack = CigtfRack(seed)
            st = open_cigtf_drivers(rack)
            res = pretest_setup(st, Run(st.clock, Journal(Path(d) / f"j{seed}.jsonl")))
            m = rack.world.misalignments
            t = [to_arcsec(m.b), to_arcsec(m.c), to_arcsec(m.a + m.d)]
            z.append([(res[f"{k}_arcsec"] - v) / res[f"{k}_sigma_arcsec"]
                      for k, v in zip(("b", "c", "north"), t, strict=True)])
            true.append(t)
            rounds.append((res["level_rounds"], res["azimuth_rounds"]))
            st.close()
    za, ta, ra = np.array(z), np.array(true), np.array(rounds)
    for i, name in enumerate(("b", "c", "a + d")):
        print(f"{name:>5}: (estimate - truth) / sigma rms {np.sqrt((za[:, i]**2).mean()):.2f}"
              f", largest {abs(za[:, i]).max():.2f}; true residual rms "
              f"{np.sqrt((ta[:, i]**2).mean()):.2f} arcsec")
    print(f"rounds: levels {ra[:, 0].mean():.1f} (most {ra[:, 0].max()}), azimuth "
          f"{ra[:, 1].mean():.1f} (most {ra[:, 1].max()}) over {n} seeds")


if __name__ == "__main__":
    main()
