"""The IEU's command parser: strict fields, the shortest period its bus can carry, and any
frame a host may send answered by exactly the reply the protocol defines
(docs/protocols.md, "IEU (CAN)")."""

from __future__ import annotations

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from config.dbc import load_dbc
from instruments.isu.ieu import (
    SAMPLE_FRAMES,
    bus_bit_rate,
    can_frame_bits,
    min_period_s,
)
from sim.timebase import ticks
from station.config.isu import load_config
from station.errors import InstrumentRefused
from station.racks.isu import SimulatedRack

DB = load_dbc()
COMMAND = DB.get_message_by_name("IEU_COMMAND")
STATUS = DB.get_message_by_name("IEU_STATUS")
ERROR = DB.get_message_by_name("IEU_ERROR")


def command(code: int, period: int = 0, seq: int = 0, byte7: int = 0) -> bytes:
    """IEU_COMMAND's bytes laid out by hand (the DBC's encoder refuses codes above 4)."""
    return (bytes([code]) + period.to_bytes(4, "little") + seq.to_bytes(2, "little")
            + bytes([byte7]))


def test_hand_layout_is_the_dbc_layout():
    assert command(1, 1000, 7) == COMMAND.encode({"Command": 1, "PeriodTicks": 1000, "Seq": 7})


# ----------------------------------------------------------------------------- the bus


def test_worst_case_frame_length_follows_the_can_frame_format():
    """Classic CAN, 11-bit identifier: 44 + 8n bits of frame with 3 of intermission, plus
    at most one stuff bit per 4 of the 34 + 8n stuffed bits (SOF to CRC)."""
    for n in range(9):
        stuffed = 1 + 11 + 1 + 1 + 1 + 4 + 8 * n + 15  # SOF, id, RTR, IDE, r0, DLC, data, CRC
        fixed = 1 + 2 + 7 + 3  # CRC delimiter, ACK slot and delimiter, EOF, intermission
        assert can_frame_bits(n) == stuffed + fixed + (stuffed - 1) // 4
    assert can_frame_bits(8) == 135  # the figure usually quoted for a full standard frame


def test_shortest_period_leaves_the_bus_room_to_recover_every_sample():
    sample = sum(can_frame_bits(DB.get_message_by_name(n).length) for n in SAMPLE_FRAMES)
    assert bus_bit_rate(DB) == 1_000_000
    t = min_period_s(DB)
    assert t * bus_bit_rate(DB) == 2 * sample + can_frame_bits(COMMAND.length)
    assert sample / (t * bus_bit_rate(DB)) < 0.5  # sampling alone takes under half the bus


def test_ieu_refuses_a_period_below_what_its_bus_carries(station, rack):
    shortest = rack.ieu.periods[0]
    s2 = rack.world.oscillator.s2_nominal
    assert (shortest - 1) * s2 < min_period_s(DB) <= shortest * s2
    with pytest.raises(InstrumentRefused) as e:
        station.ieu.start(shortest - 1)
    assert (e.value.code, e.value.instrument) == (4, "ieu")
    assert station.ieu.status()["State"] == 0
    station.ieu.start(shortest, recover=True)
    samples = [station.ieu.next_sample(timeout=1.0) for _ in range(50)]
    station.ieu.stop()
    assert [s.timer for s in samples] == [shortest] * 50
    assert [s.seq for s in samples] == list(range(samples[0].seq, samples[0].seq + 50))


# ----------------------------------------------------------------------------- any frame


def expected_reply(fid: int, data: bytes, periods: tuple[int, int]) -> int | str:
    """The protocol's answer to a host frame: an IEU_ERROR code, or "status"/"resend"."""
    if fid != COMMAND.frame_id:
        return 1
    if len(data) != 8:
        return 2
    code, period = data[0], int.from_bytes(data[1:5], "little")
    seq = int.from_bytes(data[5:7], "little")
    if code > 4 or data[7] != 0:
        return 3
    if (code != 1 and period) or (code != 4 and seq):
        return 3
    if code == 1 and not periods[0] <= period <= periods[1]:
        return 4
    return "resend" if code == 4 else "status"


def replies(rack: SimulatedRack, fid: int, data: bytes) -> list[tuple[int, dict]]:
    """The frames the IEU sends within two frame gaps of receiving a host frame."""
    ieu = rack.ieu
    ieu.output.clear()
    ieu.receive_frame(fid, data)
    rack.env.run(until=rack.env.now + ticks(2.5 * ieu.p.frame_gap_s))
    out = [(i, DB.decode_message(i, d, decode_choices=False)) for _, i, d in ieu.output]
    ieu.output.clear()
    return out


frames = st.one_of(
    st.tuples(st.integers(0, 0x7FF), st.binary(max_size=10)),  # anything
    st.tuples(st.just(COMMAND.frame_id), st.binary(min_size=8, max_size=8)),  # any payload
    st.tuples(st.just(COMMAND.frame_id),  # near-valid commands
              st.builds(command, st.integers(0, 6), st.sampled_from([0, 1, 14, 15, 20000,
                                                                     20001, 2**32 - 1]),
                        st.sampled_from([0, 1, 65535]), st.sampled_from([0, 0, 0, 1]))),
)


@given(frames)
@settings(max_examples=300, deadline=None)
def test_any_host_frame_gets_exactly_the_defined_reply(frame):
    fid, data = frame
    rack = _RACK.get()
    ieu = rack.ieu
    want = expected_reply(fid, data, ieu.periods)
    before = (ieu.running, ieu.period, ieu.seq)
    got = replies(rack, fid, data)
    if isinstance(want, int):
        assert [(i, r["Code"], r["RefId"]) for i, r in got] == [
            (ERROR.frame_id, want, fid & 0x7FF)]
        assert (ieu.running, ieu.period, ieu.seq) == before  # a refusal changes nothing
        return
    if want == "resend":  # nothing held: a fresh rack has sent no sample
        assert [(i, r["Code"]) for i, r in got] == [(ERROR.frame_id, 5)]
        return
    ((fid_out, st_),) = got
    assert fid_out == STATUS.frame_id
    code = data[0]
    assert st_["State"] == int(code == 1)
    if code == 1:
        assert st_["PeriodTicks"] == int.from_bytes(data[1:5], "little")
    if code == 2:
        assert st_["Seq"] == 0
    replies(rack, COMMAND.frame_id, command(0))  # stop again for the next example


class _RACK:
    """One rack for the property test's examples (building one costs ~0.1 s)."""

    rack: SimulatedRack | None = None

    @classmethod
    def get(cls) -> SimulatedRack:
        if cls.rack is None:
            cls.rack = SimulatedRack(load_config())
        return cls.rack


@pytest.fixture(scope="module", autouse=True)
def _close_rack():
    yield
    if _RACK.rack is not None:
        _RACK.rack.close()
        _RACK.rack = None


UNUSED_FIELDS = {
    "stop-with-a-period": command(0, period=1000),
    "status-with-a-sequence-number": command(3, seq=4),
    "resend-with-a-period": command(4, period=1, seq=0),
    "start-with-a-sequence-number": command(1, period=1000, seq=2),
    "reset-with-byte-7-set": command(2, byte7=0x55),
}


@pytest.mark.parametrize("frame", UNUSED_FIELDS.values(), ids=UNUSED_FIELDS.keys())
def test_unused_fields_are_refused_not_ignored(station, frame):
    station.ieu.bus.send(can.Message(arbitration_id=COMMAND.frame_id, data=frame,
                                     is_extended_id=False))
    with pytest.raises(InstrumentRefused) as e:
        station.ieu.status()
    assert (e.value.code, e.value.instrument) == (3, "ieu")
    assert station.ieu.status()["State"] == 0  # nothing was started or stopped
