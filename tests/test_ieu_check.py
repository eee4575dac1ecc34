"""The IEU's end-to-end check: what it detects, and that the driver never takes an altered
sample for a different one (docs/protocols.md, "End-to-end check").

A sample is five frames: four count frames and IEU_CHECK, the CRC-32C of the count frames'
32 data bytes. IEU_STATUS and IEU_ERROR carry a CRC-8/AUTOSAR. Guaranteed detection
(every error of up to 5 bits and every burst of up to 32 bits for the sample; up to 3 bits
and bursts of up to 8 for the replies) is tested exhaustively or by property; random
alterations are counted and compared with the 2^-k a k-bit check lets through.
"""

from __future__ import annotations

import math
import random
from collections import deque
from collections.abc import Callable

import can
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from config.dbc import codecs
from instruments.isu.ieu import frame_crc8, sample_crc, sample_frames, seal
from station.drivers.isu.ieu import (
    MAX_RESENDS,
    PARTS,
    DriverError,
    FailedCheck,
    Frame,
    GarbledFrame,
    IeuDriver,
    SampleAssembler,
    decode_frame,
)
from station.hil.sniff import Checker, decode

CODECS = codecs()  # the IEU's codecs, as both sides of the bus use them
DB = CODECS.db
IDS = {m.name: m.frame_id for m in DB.messages}
STATUS = DB.get_message_by_name("IEU_STATUS")
ERROR = DB.get_message_by_name("IEU_ERROR")

counts = st.tuples(
    st.integers(0, 65535),  # seq
    st.lists(st.integers(-32768, 32767), min_size=3, max_size=3),
    st.lists(st.integers(0, 65535), min_size=6, max_size=6),
    st.integers(1, 20000),  # timer
)


def genuine(seq: int = 7, g=(12, -345, 6789), a=(20001, 19999, 20010, 19990, 20005, 19995),
            timer: int = 1000) -> list[tuple[int, bytes]]:
    return sample_frames(CODECS, seq, list(g), list(a), timer)


def assemble(frames: list[tuple[int, bytes]], expected: int):
    """Feed frames to the driver's decoder and assembler; the sample it takes, or None."""
    asm = SampleAssembler(expected)
    for i, (fid, data) in enumerate(frames):
        try:
            f = decode_frame(CODECS, "ieu", "test", fid, data, float(i))
        except GarbledFrame:
            continue
        if f.name in PARTS:
            asm.add(f)
    return asm.take()


def values(s) -> tuple:
    return (s.seq, s.gyro, s.accel, s.timer, s.flags)


def flip(frames, bit: int) -> list[tuple[int, bytes]]:
    """Flip bit ``bit`` of the five frames' data bytes taken end to end."""
    out = [(fid, bytearray(d)) for fid, d in frames]
    for _, d in out:
        if bit < 8 * len(d):
            d[bit // 8] ^= 1 << (bit % 8)
            break
        bit -= 8 * len(d)
    return [(fid, bytes(d)) for fid, d in out]


SAMPLE_BITS = sum(8 * len(d) for _, d in genuine())  # 4 x 64 + 48


# ----------------------------------------------------------------------------- the codes


def syndromes(n_bytes: int, crc: Callable[[bytes], int], width: int) -> np.ndarray:
    """The check's change for each single-bit error of the data, then of the CRC field: a
    k-bit error goes undetected iff the XOR of its k syndromes is zero (a CRC is linear)."""
    base = crc(bytes(n_bytes))
    out = []
    for i in range(8 * n_bytes):
        d = bytearray(n_bytes)
        d[i // 8] ^= 1 << (i % 8)
        out.append(crc(bytes(d)) ^ base)
    out += [1 << j for j in range(width)]
    return np.array(out, dtype=np.uint64)


def undetected_weight(s: np.ndarray) -> int | None:
    """The fewest bits (up to 4) of an error the check misses, or None if none up to 4."""
    if (s == 0).any():
        return 1
    if len(np.unique(s)) < len(s):
        return 2
    i, j = np.triu_indices(len(s), 1)
    pairs = s[i] ^ s[j]
    if np.isin(pairs, s).any():
        return 3
    if len(np.unique(pairs)) < len(pairs):
        return 4
    return None


def test_sample_crc_catches_every_error_of_up_to_four_bits():
    """CRC-32C over 256 data bits + 32 check bits: no undetected error of 1-4 bits (the
    5-bit case, also clean, takes seconds: python bench/fuzz_ieu.py --distance)."""
    s = syndromes(32, lambda d: sample_crc([d[i:i + 8] for i in range(0, 32, 8)]), 32)
    assert len(s) == 288
    assert undetected_weight(s) is None


@pytest.mark.parametrize("msg", [STATUS, ERROR], ids=["status", "error"])
def test_reply_crc8_catches_every_error_of_up_to_three_bits_and_not_all_of_four(msg):
    n = msg.length - 1
    s = syndromes(n, lambda d: frame_crc8(msg.frame_id, d), 8)
    assert undetected_weight(s) == 4  # distance 4: the honest limit of 8 bits


def test_sample_crc_is_crc32c():
    """The standard check value of CRC-32C ("123456789"), so another tool can verify it."""
    assert sample_crc([b"1234", b"56789"]) == 0xE3069283


# ----------------------------------------------------------------------------- the driver


def test_genuine_sample_is_taken_with_its_counts():
    s = assemble(genuine(), 7)
    assert s is not None
    assert values(s) == (7, (12, -345, 6789), (20001, 19999, 20010, 19990, 20005, 19995),
                         1000, 0)


@given(counts)
@settings(max_examples=60, deadline=None)
def test_any_sample_round_trips(c):
    seq, g, a, timer = c
    s = assemble(sample_frames(CODECS, seq, g, a, timer), seq)
    assert s is not None and values(s) == (seq, tuple(g), tuple(a), timer, 0)


def test_every_single_bit_error_is_caught():
    frames = genuine()
    for bit in range(SAMPLE_BITS):
        assert assemble(flip(frames, bit), 7) is None, bit


@given(start=st.integers(0, SAMPLE_BITS - 1), length=st.integers(1, 32),
       inner=st.integers(0, 2**30 - 1))
@settings(max_examples=300, deadline=None)
def test_every_burst_of_up_to_32_bits_is_caught(start, length, inner):
    """A burst: first and last bit flipped, anything between (CRC-32C's guarantee)."""
    length = min(length, SAMPLE_BITS - start)
    pattern = 1 | (1 << (length - 1)) | ((inner << 1) & ((1 << max(length - 1, 1)) - 2))
    frames = genuine()
    for k in range(length):
        if pattern >> k & 1:
            frames = flip(frames, start + k)
    assert assemble(frames, 7) is None


def test_random_alterations_pass_the_sample_check_at_most_as_often_as_2_to_the_minus_32():
    """20,000 samples with their count bytes (not their Seq) replaced at random in 1-4
    frames. With a 32-bit check the expected number passing is 20,000 x 2^-32 = 4.7e-6, so
    one passing would be a defect, not bad luck."""
    rng = random.Random(13)
    frames = genuine()
    passed = 0
    for _ in range(20_000):
        bad = [(fid, bytearray(d)) for fid, d in frames]
        for k in rng.sample(range(4), rng.randint(1, 4)):
            bad[k][1][2:] = bytes(rng.getrandbits(8) for _ in range(6))
        out = [(fid, bytes(d)) for fid, d in bad]
        if out == frames:
            continue
        s = assemble(out, 7)
        passed += s is not None
    assert passed == 0


def test_random_status_frames_pass_the_crc8_about_one_in_256():
    """The same count on IEU_STATUS's 8-bit check: random payloads pass at 2^-8, within
    five binomial standard deviations (this is what the sample count above would look like
    with an 8-bit check)."""
    rng = random.Random(5)
    n = 20_000
    passed = 0
    for _ in range(n):
        data = bytes(rng.getrandbits(8) for _ in range(8))
        try:
            decode_frame(CODECS, "ieu", "test", STATUS.frame_id, data, 0.0)
            passed += 1
        except FailedCheck:
            pass
    p = 2.0**-8
    assert abs(passed - n * p) < 5 * math.sqrt(n * p * (1 - p))


def test_sealed_replies_verify_and_any_altered_byte_fails():
    data = seal(STATUS, {"State": 1, "ErrorCode": 0, "PeriodTicks": 1000, "Seq": 42})
    f = decode_frame(CODECS, "ieu", "test", STATUS.frame_id, data, 0.0)
    assert (f.sig["State"], f.sig["PeriodTicks"], f.sig["Seq"]) == (1, 1000, 42)
    for i in range(len(data)):
        for x in (1, 0x80, 0xFF):
            bad = bytearray(data)
            bad[i] ^= x
            with pytest.raises(FailedCheck, match="IEU_STATUS failed its CRC-8"):
                decode_frame(CODECS, "ieu", "test", STATUS.frame_id, bytes(bad), 0.0)


@given(fid=st.integers(-5, 0x1FFFFFFF + 5), data=st.binary(max_size=12))
@settings(max_examples=300, deadline=None)
def test_decoder_refuses_any_frame_the_project_way(fid, data):
    """Any identifier and payload: a decoded Frame of the right length, or GarbledFrame."""
    try:
        f = decode_frame(CODECS, "ieu", "test", fid, data, 0.0)
    except GarbledFrame as e:
        assert e.instrument == "ieu"
        assert "garbled frame id" in str(e) or "failed its CRC-8 check" in str(e)
        return
    assert isinstance(f, Frame) and len(f.data) == DB.get_message_by_frame_id(fid).length


# ----------------------------------------------------------------------------- recovery


class ScriptedIeu:
    """A python-can-like bus with an IEU behind it that sends ``n`` genuine samples, each
    frame through ``fault`` (which may drop, alter, repeat or add frames), and answers
    START, STOP and RESEND as the real IEU does (a resend goes ahead of later samples)."""

    def __init__(self, n: int, fault: Callable[[int, bytes], list[tuple[int, bytes]]],
                 first: int = 65530) -> None:
        rng = random.Random(n)
        self.first = first
        self.samples = {
            (first + k) % 65536: sample_frames(
                CODECS, (first + k) % 65536, [rng.randint(-500, 500) for _ in range(3)],
                [rng.randint(19000, 21000) for _ in range(6)], 1000)
            for k in range(n)}
        self.fault = fault
        self.queue: deque[tuple[int, bytes, int | None]] = deque()  # id, data, sample
        self.newest = (first - 1) % 65536  # the latest sample whose frames began to leave
        self.t = 0.0

    def send(self, msg: can.Message) -> None:
        sig = DB.decode_message(msg.arbitration_id, bytes(msg.data), decode_choices=False)
        cmd = sig["Command"]
        if cmd == 1:
            self._reply({"State": 1, "PeriodTicks": sig["PeriodTicks"], "Seq": self.first})
            for seq in self.samples:
                self.queue.extend((fid, d, seq) for fid, d in self._out(self.samples[seq]))
        elif cmd == 0:
            self.queue.clear()
            self._reply({"State": 0, "PeriodTicks": 1000, "Seq": 0})
        elif cmd == 4:
            seq = sig["Seq"]
            if (self.newest - seq) % 65536 >= 16:  # not sent yet, or no longer held
                data = seal(ERROR, {"Code": 5, "RefId": 0x080})
                self.queue.appendleft((ERROR.frame_id, data, None))
            else:
                for fid, d in reversed(self._out(self.samples[seq])):
                    self.queue.appendleft((fid, d, None))

    def _out(self, frames):
        return [g for fid, d in frames for g in self.fault(fid, d)]

    def _reply(self, sig: dict) -> None:
        self.queue.appendleft((STATUS.frame_id, seal(STATUS, sig | {"ErrorCode": 0}), None))

    def recv(self, timeout: float | None = None) -> can.Message | None:
        if not self.queue:
            return None
        fid, data, seq = self.queue.popleft()
        if seq is not None:
            self.newest = seq
        self.t += 1e-4
        return can.Message(arbitration_id=fid, data=data, timestamp=self.t,
                           is_extended_id=False, check=False)

    def shutdown(self) -> None:
        pass


def driver_on(bus: ScriptedIeu) -> IeuDriver:
    d = IeuDriver("ieu", {"interface": "virtual", "channel": "ieu-scripted"})
    d.bus.shutdown()
    d.bus = bus  # type: ignore[assignment]
    return d


def faults(rng: random.Random, drop: float, alter: float, junk: float):
    def fault(fid: int, data: bytes) -> list[tuple[int, bytes]]:
        out: list[tuple[int, bytes]] = []
        if rng.random() < junk:
            out.append((rng.choice([*IDS.values(), 0x7FF]),
                        bytes(rng.getrandbits(8) for _ in range(rng.randint(0, 8)))))
        if rng.random() < drop:
            return out
        d = bytearray(data)
        if rng.random() < alter:
            kind = rng.randrange(3)
            if kind == 0:  # one byte to another value (the fault injection's kind)
                d[rng.randrange(len(d))] ^= rng.randint(1, 255)
            elif kind == 1:  # several random bytes
                for _ in range(rng.randint(2, 5)):
                    d[rng.randrange(len(d))] = rng.getrandbits(8)
            else:  # a burst of up to 32 bits inside the frame
                first = rng.randrange(8 * len(d))
                for b in range(first, min(first + rng.randint(1, 32), 8 * len(d))):
                    if b == first or rng.random() < 0.5:
                        d[b // 8] ^= 1 << (b % 8)
        out.append((fid, bytes(d)))
        if rng.random() < junk:
            out.append((fid, bytes(d)))  # repeated
        return out

    return fault


@given(seed=st.integers(0, 2**32 - 1), drop=st.sampled_from([0.0, 0.02, 0.2]),
       alter=st.sampled_from([0.0, 0.05, 0.3]), junk=st.sampled_from([0.0, 0.05]))
@settings(max_examples=60, deadline=None)
def test_recover_mode_returns_genuine_samples_in_order_or_stops_naming_one(
        seed, drop, alter, junk):
    """Whatever happens to the frames: every sample returned is the genuine one of its
    sequence number, in order, and the only way out otherwise is a DriverError."""
    n = 25
    bus = ScriptedIeu(n, faults(random.Random(seed), drop, alter, junk))
    drv = driver_on(bus)
    got = []
    try:
        drv.start(1000, recover=True)
        while len(got) < n:
            got.append(drv.next_sample(timeout=1.0))
    except DriverError as e:
        assert e.instrument == "ieu"
    expect = list(bus.samples)
    for s, seq in zip(got, expect, strict=False):
        fid_data = assemble(bus.samples[seq], seq)
        assert fid_data is not None and values(s) == values(fid_data)
    assert [s.seq for s in got] == expect[:len(got)]
    if not (drop or alter or junk):
        assert len(got) == n and drv.recoveries == []


def test_recover_mode_gives_up_after_three_resends_naming_the_sample():
    """Sample 65531's check frame is altered every time it is sent."""
    def fault(fid, data):
        if fid == IDS["IEU_CHECK"] and data[:2] == (65531).to_bytes(2, "little"):
            return [(fid, data[:2] + bytes(4))]
        return [(fid, data)]

    drv = driver_on(ScriptedIeu(20, fault))
    drv.start(1000, recover=True)
    assert drv.next_sample().seq == 65530
    with pytest.raises(DriverError, match=f"sample 65531 failed its CRC-32C check after "
                                          f"{MAX_RESENDS} resends"):
        drv.next_sample()
    assert [r["resends"] for r in drv.recoveries] == [1, 2, 3]
    assert all(r["failed_check"] and r["seq"] == 65531 for r in drv.recoveries)


def test_plain_mode_names_the_sample_that_fails_its_check():
    def fault(fid, data):
        if fid == IDS["IEU_GYRO"] and data[:2] == (65532).to_bytes(2, "little"):
            return [(fid, data[:2] + bytes([data[2] ^ 4]) + data[3:])]
        return [(fid, data)]

    drv = driver_on(ScriptedIeu(6, fault))
    drv.start(1000)
    assert [drv.next_sample().seq for _ in range(2)] == [65530, 65531]
    with pytest.raises(DriverError, match="sample 65532 failed its CRC-32C check"):
        drv.next_sample()
    assert drv.next_sample().seq == 65533


def test_status_failing_its_check_makes_the_driver_ask_again():
    class Noisy(ScriptedIeu):
        spoiled = 0

        def _reply(self, sig):
            super()._reply(sig)
            if self.spoiled < 2:  # the first two statuses arrive altered
                self.spoiled += 1
                fid, data, _ = self.queue.popleft()
                self.queue.appendleft((fid, bytes([data[0] ^ 0x10]) + data[1:], None))

    bus = Noisy(3, lambda fid, d: [(fid, d)])
    drv = driver_on(bus)
    drv.start(1000, recover=True)
    assert drv.failed_checks == 2
    assert [drv.next_sample().seq for _ in range(3)] == [65530, 65531, 65532]


# ----------------------------------------------------------------------------- sniffer


def test_sniffer_reports_each_check():
    frames = genuine(seq=3) + genuine(seq=4)
    bad = frames[:6] + [(frames[6][0], frames[6][1][:4] + bytes([frames[6][1][4] ^ 1])
                         + frames[6][1][5:])] + frames[7:]
    status = seal(STATUS, {"State": 0, "ErrorCode": 0, "PeriodTicks": 1000, "Seq": 5})
    bad += [(STATUS.frame_id, status), (STATUS.frame_id, status[:-1] + bytes([status[-1] ^ 1])),
            (IDS["IEU_CHECK"], frames[4][1])]  # a check frame whose counts were not seen
    checker = Checker()
    recs = [decode(DB, can.Message(arbitration_id=fid, data=d, timestamp=0.0), checker)
            for fid, d in bad]
    verdicts = [(r["name"], r["check"]) for r in recs if "check" in r]
    assert verdicts == [("IEU_CHECK", "ok"), ("IEU_CHECK", "failed"), ("IEU_STATUS", "ok"),
                        ("IEU_STATUS", "failed"), ("IEU_CHECK", "incomplete")]
