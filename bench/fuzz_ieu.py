"""Fuzz targets for the IEU frame path (bench/fuzz.py --only ieu), and its checks' distances.

    python bench/fuzz.py 100000 --only ieu
    python bench/fuzz_ieu.py --distance

* ``ieu.command``: any host frame into the simulated IEU (``Ieu.receive_frame``); the
  reply must be the one docs/protocols.md defines (an IEU_ERROR code, a status echoing the
  command, the frames of a held sample).
* ``ieu.sample-decoder``: a genuine sample's five frames, mutated (bits, bytes, bursts,
  lost, repeated, swapped, truncated or extra frames, junk), into the driver's decoder
  (``decode_frame``) and assembler; the sample it takes must be exactly the one an
  independent reading of the protocol takes (five frames of the expected ``Seq``, no two
  different copies of one frame, CRC-32C matching), or none.
* ``ieu.reply-decoder``: IEU_STATUS / IEU_ERROR frames, mutated, into ``decode_frame``:
  decoded only if of the right length with a matching CRC-8.

A mutation that happens to pass a check is a well-formed frame (the protocol cannot tell it
from a genuine one): it counts as accepted, and is reported separately after the target's
line with the rate the check's width predicts (2^-32 for samples, 2^-8 for replies).
"""

from __future__ import annotations

import random
import struct
import sys
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _args import parser  # noqa: E402
from crccheck.crc import Crc8Autosar, Crc32C  # type: ignore[import-untyped]  # noqa: E402
from fuzz_core import FuzzTarget  # noqa: E402

from config.dbc import codecs  # noqa: E402
from instruments.isu.ieu import sample_frames, seal  # noqa: E402
from sim.timebase import ticks  # noqa: E402
from station.config.isu import load_config  # noqa: E402
from station.drivers.isu.ieu import PARTS, GarbledFrame, SampleAssembler, decode_frame  # noqa: E402
from station.racks.isu import SimulatedRack  # noqa: E402

CODECS = codecs()
DB = CODECS.db
NAMES = {m.frame_id: m.name for m in DB.messages}
LENGTH = {m.name: m.length for m in DB.messages}
IDS = {m.name: m.frame_id for m in DB.messages}
COUNT = PARTS[:4]
Frames = list[tuple[int, bytes]]


# ----------------------------------------------------------------------------- commands


class CommandTarget:
    """Host frames into one simulated IEU; replies compared with the protocol's."""

    def __init__(self) -> None:
        self.rack: SimulatedRack | None = None

    def setup(self) -> None:
        self.rack = SimulatedRack(load_config())

    def teardown(self) -> None:
        if self.rack is not None:
            self.rack.close()
            self.rack = None

    def frame(self, rng: random.Random) -> tuple[int, bytes]:
        kind = rng.randrange(4)
        if kind == 0:  # anything
            return rng.randrange(0x800), rng.randbytes(rng.randrange(11))
        if kind == 1:  # any payload on the command identifier
            return 0x080, rng.randbytes(rng.choice([8, 8, 8, rng.randrange(11)]))
        code = rng.choice([0, 1, 2, 3, 4, 4, rng.randrange(256)])
        period = rng.choice([0, 1000, 14, 15, 20000, 20001, rng.getrandbits(32)])
        seq = rng.choice([0, 0, rng.getrandbits(16)])
        if kind == 3:  # a valid command
            period = rng.choice([15, 1000, 20000]) if code == 1 else 0
            seq = seq if code == 4 else 0
        data = bytes([code & 0xFF]) + period.to_bytes(4, "little") + seq.to_bytes(2, "little")
        return 0x080, data + bytes([0 if kind == 3 or rng.random() < 0.8 else rng.randrange(256)])

    def expected(self, fid: int, data: bytes,
                 periods: tuple[int, int]) -> int | tuple[str, int, int, int]:
        if fid != 0x080:
            return 1
        if len(data) != 8:
            return 2
        code, period, seq, byte7 = struct.unpack("<BIHB", data)
        if code > 4 or byte7 or (code != 1 and period) or (code != 4 and seq):
            return 3
        if code == 1 and not periods[0] <= period <= periods[1]:
            return 4
        return ("status", code, period, seq)

    def run(self, rng: random.Random) -> str:
        assert self.rack is not None
        ieu, env = self.rack.ieu, self.rack.env
        fid, data = self.frame(rng)
        want = self.expected(fid, data, ieu.periods)
        ieu.output.clear()
        ieu.receive_frame(fid, data)
        env.run(until=env.now + ticks(2.5 * ieu.p.frame_gap_s))
        got = [(i, d) for _, i, d in ieu.output]
        ieu.output.clear()
        if isinstance(want, int):
            ok = len(got) == 1 and got[0][0] == IDS["IEU_ERROR"] and got[0][1][0] == want \
                and int.from_bytes(got[0][1][1:3], "little") == fid & 0x7FF
            return "rejected" if ok else "wrong"
        _, code, period, seq = want
        if code == 4:  # resend: nothing is ever held here (sampling is stopped at once)
            ok = [(i, d[0]) for i, d in got] == [(IDS["IEU_ERROR"], 5)]
            return "rejected" if ok else "wrong"
        ok = len(got) == 1 and got[0][0] == IDS["IEU_STATUS"]
        if ok:
            st = got[0][1]
            state, per = st[0] & 0x0F, int.from_bytes(st[1:5], "little")
            ok = state == int(code == 1) and (code != 1 or per == period) \
                and (code != 2 or st[5:7] == b"\0\0")
        if code == 1:
            ieu.receive_frame(0x080, bytes(8))  # stop before the next input
            env.run(until=env.now + ticks(2.5 * ieu.p.frame_gap_s))
            ieu.output.clear()
        return "accepted" if ok else "wrong"


# ----------------------------------------------------------------------------- samples


def mutate(frames: Frames, rng: random.Random) -> Frames:
    """One random kind of damage to a sample's frames (or none)."""
    out = [(fid, bytearray(d)) for fid, d in frames]
    kind = rng.randrange(13)
    k = rng.randrange(len(out))
    d = out[k][1]
    if kind == 0:
        pass
    elif kind == 1:  # 1-3 bit flips anywhere
        for _ in range(rng.randint(1, 3)):
            j = rng.randrange(len(out))
            b = rng.randrange(8 * len(out[j][1]))
            out[j][1][b // 8] ^= 1 << (b % 8)
    elif kind == 2:  # 1-4 bytes to random values
        for _ in range(rng.randint(1, 4)):
            j = rng.randrange(len(out))
            out[j][1][rng.randrange(len(out[j][1]))] = rng.getrandbits(8)
    elif kind == 3:  # a burst of up to 32 bits in one frame
        first = rng.randrange(8 * len(d))
        for b in range(first, min(first + rng.randint(1, 32), 8 * len(d))):
            if b == first or rng.random() < 0.5:
                d[b // 8] ^= 1 << (b % 8)
    elif kind == 4:  # one frame's counts replaced at random (Seq kept)
        d[2:] = rng.randbytes(len(d) - 2)
    elif kind == 5:  # a frame lost
        del out[k]
    elif kind == 6:  # a frame repeated, the copy altered or not
        c = bytearray(d)
        if rng.random() < 0.5:
            c[rng.randrange(len(c))] ^= rng.randint(1, 255)
        out.insert(rng.randrange(len(out) + 1), (out[k][0], c))
    elif kind == 7:  # two frames' identifiers swapped
        j = rng.randrange(len(out))
        (a, da), (b, db) = out[k], out[j]
        out[k], out[j] = (b, da), (a, db)
    elif kind == 8:  # a frame truncated or lengthened
        out[k] = (out[k][0], d[:rng.randrange(len(d))] if rng.random() < 0.5
                  else d + rng.randbytes(rng.randint(1, 3)))
    elif kind == 9:  # junk frames in between
        for _ in range(rng.randint(1, 4)):
            out.insert(rng.randrange(len(out) + 1),
                       (rng.choice([*NAMES, rng.randrange(0x800)]),
                        bytearray(rng.randbytes(rng.randrange(9)))))
    elif kind == 10:  # one frame's Seq changed
        d[0:2] = rng.getrandbits(16).to_bytes(2, "little")
    elif kind == 11:  # frames out of order
        rng.shuffle(out)
    else:  # everything random
        out = [(rng.choice([*NAMES, rng.randrange(0x800)]), bytearray(rng.randbytes(
            rng.randrange(9)))) for _ in range(rng.randint(1, 7))]
    return [(fid, bytes(d)) for fid, d in out]


def protocol_sample(frames: Frames, seq: int) -> tuple | None:
    """The sample ``seq`` the protocol defines from these frames, read independently of the
    driver: each of the five frames of that Seq once (or repeated identically), right
    lengths, CRC-32C of the count frames equal to IEU_CHECK's."""
    parts: dict[str, bytes] = {}
    for fid, d in frames:
        name = NAMES.get(fid)
        if name not in PARTS or len(d) != LENGTH[name]:
            continue
        if int.from_bytes(d[:2], "little") != seq:
            continue
        if parts.setdefault(name, d) != d:
            return None
    if len(parts) < len(PARTS):
        return None
    if Crc32C.calc(b"".join(parts[p] for p in COUNT)) != int.from_bytes(
            parts["IEU_CHECK"][2:6], "little"):
        return None
    g = struct.unpack("<3h", parts["IEU_GYRO"][2:])
    a = struct.unpack("<3H", parts["IEU_ACCEL_A"][2:]) + struct.unpack(
        "<3H", parts["IEU_ACCEL_B"][2:])
    timer, flags = struct.unpack("<IH", parts["IEU_TIMER"][2:])
    return (seq, g, a, timer, flags)


class SampleTarget:
    def __init__(self) -> None:
        self.collisions = 0  # damaged samples that still passed the check (well-formed)
        self.damaged = 0

    def setup(self) -> None:
        self.collisions = self.damaged = 0

    def teardown(self) -> None:
        print(f"    ieu.sample-decoder: {self.damaged} samples whose frames changed, "
              f"{self.collisions} passed the CRC-32C (expected {self.damaged * 2.0**-32:.1e})")

    def run(self, rng: random.Random) -> str:
        seq = rng.getrandbits(16)
        g = [rng.randint(-32768, 32767) for _ in range(3)]
        a = [rng.randint(0, 65535) for _ in range(6)]
        genuine_frames = sample_frames(CODECS, seq, g, a, rng.randint(15, 20000))
        frames = mutate(genuine_frames, rng)
        want = protocol_sample(frames, seq)
        truth = protocol_sample(genuine_frames, seq)
        asm = SampleAssembler(seq)
        for i, (fid, d) in enumerate(frames):
            try:
                f = decode_frame(CODECS, "ieu", "fuzz", fid, d, float(i))
            except GarbledFrame:
                continue
            if f.name in PARTS:
                asm.add(f)
        s = asm.take()
        got = None if s is None else (s.seq, s.gyro, s.accel, s.timer, s.flags)
        if sorted(frames) != sorted(genuine_frames):
            self.damaged += 1
            self.collisions += want is not None and want != truth
        if got != want:
            return "wrong"
        return "rejected" if got is None else "accepted"


# ----------------------------------------------------------------------------- replies


def genuine_reply(rng: random.Random) -> tuple[int, bytes]:
    """A sealed IEU_STATUS or IEU_ERROR with random fields."""
    if rng.random() < 0.5:
        msg = DB.get_message_by_name("IEU_STATUS")
        sig = {"State": rng.randint(0, 1), "ErrorCode": rng.randint(0, 5),
               "PeriodTicks": rng.randint(15, 20000), "Seq": rng.getrandbits(16)}
    else:
        msg = DB.get_message_by_name("IEU_ERROR")
        sig = {"Code": rng.randint(1, 5), "RefId": rng.randrange(0x800)}
    return msg.frame_id, seal(msg, sig)


def damage(data: bytes, rng: random.Random) -> tuple[bytes, bool]:
    """None, a bit, a byte, all bytes, or the length and all bytes of a reply changed; and
    whether the damage is beyond what the CRC-8 always catches (up to 3 bits, a burst of
    up to 8)."""
    d = bytearray(data)
    kind = rng.randrange(5)
    if kind == 1:
        b = rng.randrange(8 * len(d))
        d[b // 8] ^= 1 << (b % 8)
    elif kind == 2:
        d[rng.randrange(len(d))] = rng.getrandbits(8)
    elif kind == 3:
        d = bytearray(rng.randbytes(len(d)))
    elif kind == 4:
        d = bytearray(rng.randbytes(rng.randrange(11)))
    return bytes(d), kind >= 3


class ReplyTarget:
    def __init__(self) -> None:
        self.collisions = 0  # damaged replies that still passed the CRC-8 (well-formed)
        self.damaged = 0
        self.chances = 0  # damaged at random beyond the CRC's guarantee, at the right length

    def setup(self) -> None:
        self.collisions = self.damaged = self.chances = 0

    def teardown(self) -> None:
        print(f"    ieu.reply-decoder: {self.damaged} replies damaged, {self.chances} at random "
              f"beyond the CRC-8's guarantee; {self.collisions} passed it "
              f"(expected {self.chances / 256:.0f})")

    def run(self, rng: random.Random) -> str:
        fid, genuine = genuine_reply(rng)
        data, random_damage = damage(genuine, rng)
        name = NAMES[fid]
        ok = len(data) == LENGTH[name] and Crc8Autosar.calc(
            fid.to_bytes(2, "little") + data[:-1]) == data[-1]
        if data != genuine:
            self.damaged += 1
            self.collisions += ok
            self.chances += random_damage and len(data) == LENGTH[name]
        try:
            f = decode_frame(CODECS, "ieu", "fuzz", fid, data, 0.0)
        except GarbledFrame:
            return "wrong" if ok else "rejected"
        if not ok:
            return "wrong"
        want = ({"State": data[0] & 0xF, "ErrorCode": data[0] >> 4,
                 "PeriodTicks": int.from_bytes(data[1:5], "little"),
                 "Seq": int.from_bytes(data[5:7], "little"), "Crc": data[7]}
                if name == "IEU_STATUS" else
                {"Code": data[0], "RefId": int.from_bytes(data[1:3], "little"), "Crc": data[3]})
        return "accepted" if f.sig == want else "wrong"


_command = CommandTarget()
_samples = SampleTarget()
_replies = ReplyTarget()

TARGETS = [
    FuzzTarget("ieu.command", _command.run, _command.setup, _command.teardown),
    FuzzTarget("ieu.sample-decoder", _samples.run, _samples.setup, _samples.teardown),
    FuzzTarget("ieu.reply-decoder", _replies.run, _replies.setup, _replies.teardown),
]


# ----------------------------------------------------------------------------- distances


def distances() -> None:
    """Print each check's smallest undetected error weight, from its error syndromes."""
    import numpy as np
    from crccheck.crc import Crc8Autosar as C8
    from crccheck.crc import Crc32C as C32

    def syndromes(n: int, crc: Callable[[bytes], int], width: int):
        base = crc(bytes(n))
        s = []
        for i in range(8 * n):
            d = bytearray(n)
            d[i // 8] ^= 1 << (i % 8)
            s.append(crc(bytes(d)) ^ base)
        return np.array(s + [1 << j for j in range(width)], dtype=np.uint64)

    def weight(s, up_to: int) -> str:
        n = len(s)
        if (s == 0).any():
            return "1"
        if len(np.unique(s)) < n:
            return "2"
        i, j = np.triu_indices(n, 1)
        pairs = s[i] ^ s[j]
        if np.isin(pairs, s).any():
            return "3"
        if len(np.unique(pairs)) < len(pairs):
            return "4"
        if up_to >= 5:
            ps = np.sort(pairs)
            for a in range(n - 2):
                b, c = np.triu_indices(n - a - 1, 1)
                if np.isin(s[a] ^ s[a + 1 + b] ^ s[a + 1 + c], ps).any():
                    return "5"
        return f"more than {up_to}"

    checks = [
        ("sample, CRC-32C over 32 bytes", 32, lambda d: C32.calc(d), 32, 5),
        ("IEU_STATUS, CRC-8 over 7 bytes", 7,
         lambda d: C8.calc(IDS["IEU_STATUS"].to_bytes(2, "little") + d), 8, 4),
        ("IEU_ERROR, CRC-8 over 3 bytes", 3,
         lambda d: C8.calc(IDS["IEU_ERROR"].to_bytes(2, "little") + d), 8, 4),
    ]
    for name, n, crc, width, up_to in checks:
        s = syndromes(n, crc, width)
        print(f"{name}: {len(s)} bits with the check; smallest undetected error: "
              f"{weight(s, up_to)} bits")


def main(argv: list[str] | None = None) -> None:
    """``--distance``: each check's distances; without it, this module's documentation."""
    ap = parser(__doc__)
    ap.add_argument("--distance", action="store_true",
                    help="print each check's smallest undetected error weight")
    if ap.parse_args(argv).distance:
        distances()
    else:
        print(__doc__)


if __name__ == "__main__":
    main()
