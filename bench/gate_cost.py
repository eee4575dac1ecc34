"""Cost of a counter gate against its length, and the speed of a whole six-counter position.

Prints: the wall time of a 30-minute "measure X-Y" gate and of a 1-second gate (each on a
fresh rack, so no cached integral helps), their ratio (target <= 1.2, issue 17), and the
simulated seconds per wall second of a 30-minute position with all six counters on the
strings. ``gate_cost_ratio`` is importable (bench/speed.py).
"""

from __future__ import annotations

import statistics
import time

from _args import parser

from station.config.isu import load_config
from station.racks.isu import SimulatedRack, open_isu_drivers


def _setup(seed: int):
    cfg = load_config(seed=seed)
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    for ax, deg in zip((1, 2, 3, 4), (0.0, 90.0, 0.0, 0.0), strict=True):
        st.table.move(ax, deg)
    st.table.wait_still()
    return rack, st


def one_gate(seconds: float, seed: int) -> float:
    rack, st = _setup(seed)
    st.patch_panel.connect("A1S1", 1, "X")
    st.patch_panel.connect("OSC1", 1, "Z")
    st.counters[1].set_mode("measure X-Y")
    st.counters[1].set_preset(int(seconds * 20000))
    t0 = time.perf_counter()
    st.counters[1].operate()
    st.counters[1].read(timeout=seconds * 2 + 10)
    dt = time.perf_counter() - t0
    st.close()
    rack.close()
    return dt


def six_counter_position(seconds: float, seed: int) -> tuple[float, float]:
    rack, st = _setup(seed)
    lines = ("A1S1", "A1S2", "A2S1", "A2S2", "A3S1", "A3S2")
    for c, line in enumerate(lines, start=1):
        st.patch_panel.connect(line, c, "X")
        st.patch_panel.connect("OSC1", c, "Z")
        st.counters[c].set_mode("measure X-Y")
        st.counters[c].set_preset(int(seconds * 20000))
    s0 = st.clock.now()
    t0 = time.perf_counter()
    for c in range(1, 7):
        st.counters[c].operate()
    for c in range(1, 7):
        st.counters[c].read(timeout=seconds * 2 + 10)
    wall = time.perf_counter() - t0
    sim = st.clock.now() - s0
    st.close()
    rack.close()
    return sim, wall


def gate_times(repeats: int = 15) -> tuple[list[float], list[float]]:
    """Wall seconds of ``repeats`` 1-second and 30-minute gates, interleaved so that machine
    load affects both alike (seeds 1..repeats, one fresh rack each)."""
    one_gate(1.0, 99)  # warm imports and caches of the interpreter
    shorts, longs = [], []
    for s in range(1, repeats + 1):
        shorts.append(one_gate(1.0, s))
        longs.append(one_gate(1800.0, s))
    return shorts, longs


def gate_cost_ratio(repeats: int = 15) -> float:
    """Median wall time of a 30-minute gate over that of a 1-second gate (issue 17: <= 1.2)."""
    shorts, longs = gate_times(repeats)
    return statistics.median(longs) / statistics.median(shorts)


def main(argv: list[str] | None = None) -> None:
    parser(__doc__).parse_args(argv)
    shorts, longs = gate_times(15)
    short, long = statistics.median(shorts), statistics.median(longs)
    print(f"1-second gate:  {short * 1e3:8.2f} ms wall (median of 15)")
    print(f"30-minute gate: {long * 1e3:8.2f} ms wall (median of 15)")
    print(f"ratio 30 min / 1 s: {long / short:.2f}  (target <= 1.2; medians)")
    print(f"ratio of the fastest runs: {min(longs) / min(shorts):.2f}  (least disturbed by load)")
    sim, wall = six_counter_position(1800.0, 7)
    print(
        f"six-counter 30-minute position: {sim:.1f} s simulated in {wall * 1e3:.1f} ms wall"
        f" = {sim / wall:,.0f} simulated s per wall s"
    )


if __name__ == "__main__":
    main()
