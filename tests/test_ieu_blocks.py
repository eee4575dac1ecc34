"""IEU samples counted in blocks (instruments.isu.ieu_block): every sample's counts are
exactly those of the direct evaluation (each line's count over the sample, asked for at
the latch instant), over streams that cross table commands, a STOP and START again, and a
RESET, with random periods; and the block really is reused between world changes."""

from __future__ import annotations

import random

import numpy as np
import pytest

from instruments.isu.ieu import ACCEL_LINES, GYRO_LINES
from instruments.isu.ieu_block import SampleBlocks
from station.config.isu import load_config
from station.racks.isu import SimulatedRack, open_isu_drivers


class Audit:
    """Wraps the IEU's counting: the block's counts beside the direct evaluation's."""

    def __init__(self, rack: SimulatedRack) -> None:
        self.rack = rack
        self.pairs: list[tuple[tuple, tuple]] = []
        self.computed = 0
        ieu = rack.ieu
        counts = ieu._counts
        w = rack.world

        def audited(t0: float, t1: float) -> tuple[list[int], list[int], int, float]:
            out = counts(t0, t1)
            direct = ([w.line(n).count(t0, t1) for n in GYRO_LINES],
                      [w.line(n).count(t0, t1) for n in ACCEL_LINES],
                      w.line("OSC2").count(t0, t1), t1)
            self.pairs.append((tuple(map(str, out)), tuple(map(str, direct))))
            return out

        ieu._counts = audited  # type: ignore[method-assign]
        compute = SampleBlocks._compute

        def counted(blocks: SampleBlocks, t0: float) -> None:
            self.computed += 1
            compute(blocks, t0)

        self._patch = counted


@pytest.mark.parametrize("seed", [3, 11])
def test_block_counts_are_the_direct_counts_across_table_commands_and_restarts(
        seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    rnd = random.Random(seed)
    cfg = load_config(seed=seed)
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    audit = Audit(rack)
    monkeypatch.setattr(SampleBlocks, "_compute", audit._patch)
    lo = rack.ieu.periods[0]
    try:
        received = 0
        for leg in range(4):
            period = rnd.randint(lo, 3000)
            st.ieu.start(period, recover=True)
            for _ in range(rnd.randint(30, 60)):
                st.ieu.next_sample(timeout=5.0)
                received += 1
            # a table command while sampling: the world's future changes under the block
            st.table.move(rnd.randint(1, 4), rnd.uniform(-90.0, 90.0))
            for _ in range(rnd.randint(5, 20)):
                st.ieu.next_sample(timeout=5.0)
                received += 1
            st.table.stop()
            for _ in range(rnd.randint(5, 20)):
                st.ieu.next_sample(timeout=5.0)
                received += 1
            if leg % 2:
                st.ieu.reset()
            else:
                st.ieu.stop()
    finally:
        st.close()
        rack.close()
    assert len(audit.pairs) >= received
    for block, direct in audit.pairs:
        assert block == direct
    assert audit.computed < len(audit.pairs) / 3  # blocks are reused between changes


def test_block_levels_are_the_scalar_levels_at_random_times() -> None:
    """One vectorised evaluation of a line's phase has, at every time, the bits of the
    scalar phase (so floors, and counts, cannot differ)."""
    cfg = load_config(seed=5)
    rack = SimulatedRack(cfg)
    try:
        w = rack.world
        t = np.sort(np.random.default_rng(5).uniform(0.0, 900.0, 400))
        for name in (*GYRO_LINES, *ACCEL_LINES, "OSC1", "OSC2"):
            line = w.line(name)
            src = line.last_sample
            scalar = np.array([line.phase(src(float(x))) for x in t])
            block = line._phases(np.array([src(float(x)) for x in t]))  # type: ignore[misc]
            assert np.array_equal(scalar, block), name
            assert list(line.levels(t)) == [line.level(float(x)) for x in t], name
    finally:
        rack.close()


def test_table_crc32c_is_crccheck_crc32c_on_both_sides_of_the_bus() -> None:
    """The IEU's and the driver's table-driven CRC-32C give crccheck's value on any bytes."""
    from crccheck.crc import Crc32C

    from instruments.isu.ieu import crc32c as ieu_crc
    from station.drivers.isu.ieu import crc32c as driver_crc

    rng = random.Random(32)
    for n in (0, 1, 7, 32, 33, 100):
        for _ in range(50):
            data = bytes(rng.getrandbits(8) for _ in range(n))
            assert ieu_crc(data) == driver_crc(data) == int(Crc32C.calc(data))
    assert ieu_crc(b"123456789") == 0xE3069283  # the CRC-32C check value


def test_sample_frames_are_the_strictly_encoded_frames() -> None:
    """Frames encoded without cantools' range check are byte for byte the checked ones,
    clipped counts and overflow flag included."""
    from config.dbc import codecs
    from instruments.isu.ieu import COUNT_FRAMES, sample_crc, sample_frames

    enc = codecs()
    db = enc.db
    rng = random.Random(7)
    for _ in range(200):
        seq = rng.randrange(65536)
        g = [rng.randint(-40000, 40000) for _ in range(3)]
        a = [rng.randint(-10, 70000) for _ in range(6)]
        timer = rng.randint(15, 20000)
        got = sample_frames(enc, seq, g, a, timer)
        gc = [max(-32768, min(32767, x)) for x in g]
        ac = [max(0, min(65535, x)) for x in a]
        flags = int(gc != g or ac != a)
        sigs = ({"Seq": seq, "Gyro1": gc[0], "Gyro2": gc[1], "Gyro3": gc[2]},
                {"Seq": seq, "A1S1": ac[0], "A1S2": ac[1], "A2S1": ac[2]},
                {"Seq": seq, "A2S2": ac[3], "A3S1": ac[4], "A3S2": ac[5]},
                {"Seq": seq, "Timer": timer, "Flags": flags})
        want = [(db.get_message_by_name(n).frame_id,
                 bytes(db.get_message_by_name(n).encode(s, strict=True)))
                for n, s in zip(COUNT_FRAMES, sigs, strict=True)]
        check = db.get_message_by_name("IEU_CHECK")
        crc = sample_crc([d for _, d in want])
        want.append((check.frame_id, bytes(check.encode({"Seq": seq, "Crc": crc}, strict=True))))
        assert got == want
