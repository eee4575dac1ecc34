"""Wall time of one 0.1 s IEU sample over a long static stream, as a procedure streams it.

The ISU rests on the table (a position of the calibration, then still); the IEU samples
every 1000 S2^T pulses (0.1 s) and the driver returns each sample whole and verified
(recover mode, as the alignment collects). Prints wall seconds per sample and the wall time
a 24-hour noise record would take at that rate. ``ieu_cost_per_sample`` is importable
(bench/speed.py).

Usage: python bench/ieu_stream.py [HOURS]   (default 4)
"""

from __future__ import annotations

import time

from _args import parser, positive

from station.config.isu import load_config
from station.racks.isu import SimulatedRack, open_isu_drivers

PERIOD_TICKS = 1000  # S2^T pulses a sample: 0.1 s


def ieu_cost_per_sample(hours: float, seed: int = 1) -> float:
    """Wall seconds per 0.1 s IEU sample, streaming ``hours`` of samples with the ISU at rest."""
    cfg = load_config(seed=seed)
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    try:
        for ax, deg in zip((1, 2, 3, 4), (0.0, 90.0, 0.0, 0.0), strict=True):
            st.table.move(ax, deg)
        st.table.wait_still()
        n = max(1, round(hours * 3600.0 / 0.1))
        t0 = time.perf_counter()
        st.ieu.start(PERIOD_TICKS, recover=True)
        for _ in range(n):
            st.ieu.next_sample(timeout=5.0)
        st.ieu.stop()
        return (time.perf_counter() - t0) / n
    finally:
        st.close()
        rack.close()


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__)
    ap.add_argument("hours", metavar="HOURS", nargs="?", type=positive, default=4.0,
                    help="simulated hours of samples streamed (default 4)")
    a = ap.parse_args(argv)
    hours = a.hours
    ieu_cost_per_sample(0.01)  # warm imports and caches of the interpreter
    per = ieu_cost_per_sample(hours)
    print(f"IEU stream of {hours:g} h at 0.1 s: {per * 1e3:.4f} ms wall per sample "
          f"(target <= 0.2 ms)")
    print(f"a 24-hour noise record at this rate: {per * 864000 / 60:.1f} min wall")


if __name__ == "__main__":
    main()
