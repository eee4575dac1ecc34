"""Interface electronics unit (CAN): accumulating registers sampled on S2^T pulses.

On START the IEU latches its registers on every PeriodTicks-th S2^T pulse and sends one
sample as five frames sharing a sequence number: gyro, accelerometer A and B, timer, and a
closing IEU_CHECK whose CRC-32C covers the four count frames (the end-to-end check the
driver verifies). Registers are read and cleared at the same edge, so consecutive samples
telescope: no count is ever lost between reads. Frames are defined in config/ieu.dbc.

IEU_STATUS and IEU_ERROR carry a CRC-8 of their own. Commands are parsed strictly: a wrong
identifier or length, an unknown command, a nonzero field the command does not read, or a
period outside what the IEU and its bus can sustain is refused with IEU_ERROR.

The IEU keeps the frames of the last ``history_len`` samples since the latest START.
RESEND (Command 4, with the sample's sequence number in the command's ``Seq``) sends that
sample's five frames again, exactly as first sent; it is the host's way of recovering a
frame lost or failing its check on the bus. A sample no longer (or never) held is refused
with IEU_ERROR code 5. A resend is answered by the frames themselves, not by IEU_STATUS, so
it never disturbs the command/status pairing.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import cantools
import crc32c as _crc32c
import simpy
from crccheck.crc import Crc8Autosar

from config.dbc import Codecs, codecs
from instruments.isu.ieu_block import SampleBlocks
from instruments.isu.params import IeuParams
from sim.isu.pulses import PulseLine
from sim.isu.world import World
from sim.timebase import ticks, ticks_ceil

if TYPE_CHECKING:
    from instruments.output_faults import FrameFault

GYRO_LINES = ("G1", "G2", "G3")
ACCEL_LINES = ("A1S1", "A1S2", "A2S1", "A2S2", "A3S1", "A3S2")
CMD_STOP, CMD_START, CMD_RESET, CMD_STATUS, CMD_RESEND = 0, 1, 2, 3, 4
ERR_ID, ERR_DLC, ERR_CMD, ERR_PERIOD, ERR_RESEND = 1, 2, 3, 4, 5
HISTORY_LEN = 16  # samples held for RESEND (1.6 s at 1000 S2^T pulses, 0.1 s, a sample)
COUNT_FRAMES = ("IEU_GYRO", "IEU_ACCEL_A", "IEU_ACCEL_B", "IEU_TIMER")
SAMPLE_FRAMES = (*COUNT_FRAMES, "IEU_CHECK")
# Fields each command reads; every other field of IEU_COMMAND must be zero.
COMMAND_FIELDS = {CMD_STOP: (), CMD_START: ("PeriodTicks",), CMD_RESET: (),
                  CMD_STATUS: (), CMD_RESEND: ("Seq",)}



def decode_ints(msg: cantools.database.can.Message, data: bytes) -> dict[str, int]:
    """A frame's signals as integers (every IEU signal is an integer count or code)."""
    sig = cast(dict[str, Any], msg.decode(bytes(data), decode_choices=False))
    return {k: int(v) for k, v in sig.items()}


# ----- the bus's capacity and the shortest sample period -----


def can_frame_bits(n_bytes: int) -> int:
    """Worst-case bus time of a classic CAN data frame with an 11-bit identifier, in bits.

    34 + 8n bits (SOF to CRC) are subject to bit stuffing, at worst one stuff bit per four
    bits after the first; then CRC delimiter, ACK, end of frame and the 3-bit intermission.
    8 data bytes: 135 bits, 135 us at 1 Mbit/s.
    """
    stuffed = 34 + 8 * n_bytes
    return stuffed + (stuffed - 1) // 4 + 13


def bus_bit_rate(db: cantools.database.can.Database) -> int:
    """The IEU bus's bit rate, bit/s (the DBC's ``Baudrate`` attribute)."""
    if db.dbc is None or "Baudrate" not in db.dbc.attributes:
        raise ValueError("the IEU database declares no Baudrate")
    return int(db.dbc.attributes["Baudrate"].value)


def min_period_s(db: cantools.database.can.Database) -> float:
    """Shortest sample period the bus sustains with room to recover every sample once.

    Each period must carry the sample's five frames, a RESEND command for it and the five
    frames again: a sampling that fills more than half the bus leaves no time to recover
    a frame, and the frames fall behind the latches without bound.
    """
    sample = sum(can_frame_bits(db.get_message_by_name(n).length) for n in SAMPLE_FRAMES)
    command = can_frame_bits(db.get_message_by_name("IEU_COMMAND").length)
    return (2 * sample + command) / bus_bit_rate(db)


def _latch_edge(s2: PulseLine, t: float, n: int) -> float:
    """The n-th S2^T pulse after t: the master oscillator runs on whatever the table does,
    so its line always has one (a None here is a broken world, not a stopped table)."""
    edge = s2.edge_after(t, n)
    if edge is None:
        raise RuntimeError(f"the IEU's S2^T line has no edge {n} pulse(s) after t = {t:.6f} s")
    return edge


# ----- end-to-end checks -----


def crc32c(data: bytes) -> int:
    """CRC-32C of ``data``, the value crccheck's ``Crc32C`` gives, from the ``crc32c``
    package's C code (a sample's 32 bytes in about 0.5 us)."""
    return int(_crc32c.crc32c(data))


def sample_crc(count_frames: Sequence[bytes]) -> int:
    """CRC-32C of the data bytes of a sample's four count frames, in the order of COUNT_FRAMES."""
    return crc32c(b"".join(bytes(d) for d in count_frames))


def frame_crc8(frame_id: int, protected: bytes) -> int:
    """CRC-8/AUTOSAR of a frame's identifier (2 bytes, little-endian) and protected bytes."""
    return int(Crc8Autosar.calc(frame_id.to_bytes(2, "little") + bytes(protected)))


def seal(msg: cantools.database.can.Message, sig: dict) -> bytes:
    """Encode ``sig`` with the message's ``Crc`` byte set to the CRC-8 of the other bytes."""
    crc_sig = msg.get_signal_by_name("Crc")
    at = crc_sig.start // 8
    data = bytearray(msg.encode(sig | {"Crc": 0}))
    data[at] = frame_crc8(msg.frame_id, bytes(data[:at] + data[at + 1:]))
    return bytes(data)


# ----- commands in -----


@dataclass(frozen=True)
class Command:
    code: int
    period: int
    seq: int


def parse_command(db: cantools.database.can.Database, arbitration_id: int, data: bytes,
                  periods: tuple[int, int]) -> Command | int:
    """The command a host frame carries, or the IEU_ERROR code refusing it.

    ``periods`` is the accepted PeriodTicks range of START (both ends included).
    """
    msg = db.get_message_by_name("IEU_COMMAND")
    if arbitration_id != msg.frame_id:
        return ERR_ID
    if len(data) != msg.length:
        return ERR_DLC
    if data[7] != 0:
        return ERR_CMD  # byte 7 carries nothing
    sig = decode_ints(msg, data)
    code = sig["Command"]
    if code not in COMMAND_FIELDS:
        return ERR_CMD
    if any(sig[f] for f in ("PeriodTicks", "Seq") if f not in COMMAND_FIELDS[code]):
        return ERR_CMD
    period = sig["PeriodTicks"]
    if code == CMD_START and not periods[0] <= period <= periods[1]:
        return ERR_PERIOD
    return Command(code, period, sig["Seq"])


# served in real time: a sample's counts take about 0.8 ms of wall time (bench/hil_latency.py)
LOOKAHEAD_WALL_S = 0.003
# a served IEU refuses START below 200 S2^T pulses (20 ms): at the bus minimum (15) counting
# one sample takes 63 % of the simulation thread and the rack slips (docs/hil.md)
SERVED_MIN_PERIOD = 200


class Ieu:
    ident = "ISU-LAB,IEU,0,1.0"

    def __init__(self, name: str, world: World, p: IeuParams) -> None:
        self.name = name
        self.world = world
        self.env = world.env
        self.p = p
        self.codecs = codecs()
        self.db = self.codecs.db
        s2 = world.oscillator.s2_nominal
        longest = int(p.max_period_s / s2) + 1
        while longest * s2 > p.max_period_s:
            longest -= 1
        # START's PeriodTicks range: what the bus can carry, what the registers can hold
        self.periods = (math.ceil(min_period_s(self.db) / s2 - 1e-9), longest)
        self.output: deque[tuple[float, int, bytes]] = deque()
        self.listeners: list[Callable[[float, int, bytes], None]] = []
        self.running = False
        self.period = 1000
        self.seq = 0
        self.error_code = 0
        self._proc: simpy.Process | None = None
        self._blocks: SampleBlocks | None = None  # the current sampling's blocks of counts
        self.drop_every = 0  # fault injection: drop every n-th sample's gyro frame
        self.silent = False
        # real time only: count a sample this long (simulated s) before it is latched, so
        # the frames leave on time; a world change in between (table command, re-patch)
        # makes it count again at the latch instant. Zero in virtual time.
        self.lookahead_s = 0.0
        self.frame_fault: FrameFault | None = None  # fault injection: delayed, lost, altered frames
        self.history_len = HISTORY_LEN  # fault injection: 0 makes every RESEND fail
        self.history: deque[tuple[int, list[tuple[int, bytes]]]] = deque()

    def serve_in_real_time(self, speed: float) -> None:
        """Prepare to be served by a real-time server at ``speed``: count each sample a
        little ahead so its frames leave at the latch instant, and refuse START below
        ``SERVED_MIN_PERIOD`` (docs/hil.md)."""
        self.lookahead_s = LOOKAHEAD_WALL_S * speed
        lo, hi = self.periods
        self.periods = (max(lo, SERVED_MIN_PERIOD), hi)

    # ----- frames in -----
    def receive_frame(self, arbitration_id: int, data: bytes) -> None:
        cmd = parse_command(self.db, arbitration_id, data, self.periods)
        if isinstance(cmd, int):
            return self._refuse(cmd, arbitration_id)
        if cmd.code == CMD_START:
            self._stop()
            self.history.clear()  # a resend serves the samples of this sampling only
            self.period = cmd.period
            self.running = True
            self._proc = self.env.process(self._sample_loop())
        elif cmd.code == CMD_STOP:
            self._stop()
        elif cmd.code == CMD_RESET:
            self._stop()
            self.seq = 0
            self.history.clear()
        elif cmd.code == CMD_RESEND:
            return self._resend(cmd.seq, arbitration_id)
        self._send_now(
            "IEU_STATUS",
            {
                "State": int(self.running),
                "PeriodTicks": self.period,
                "Seq": self.seq,
                "ErrorCode": self.error_code,
            },
        )

    def _resend(self, seq: int, ref: int) -> None:
        held = dict(self.history)
        if seq not in held:
            return self._refuse(ERR_RESEND, ref)
        t = self.world.now
        for i, (fid, data) in enumerate(held[seq], start=1):
            self._send_at(t + i * self.p.frame_gap_s, fid, data)

    def _refuse(self, code: int, ref: int) -> None:
        self.error_code = code
        self._send_now("IEU_ERROR", {"Code": code, "RefId": ref & 0x7FF})

    def _stop(self) -> None:
        self.running = False
        if self._proc is not None and self._proc.is_alive:
            self._proc.interrupt()
        self._proc = None

    # ----- sampling -----
    def _sample_loop(self) -> Generator[simpy.Event, Any, None]:
        w = self.world
        s2 = w.line("OSC2")
        period = self.period
        self._blocks = SampleBlocks(w, [w.line(n) for n in (*GYRO_LINES, *ACCEL_LINES, "OSC2")],
                                    lambda t: _latch_edge(s2, t, period),
                                    period * w.oscillator.s2_nominal)
        try:
            t_prev = _latch_edge(s2, w.now, 1)
            yield self.env.timeout(max(0, ticks_ceil(t_prev) - self.env.now))
            while self.running:
                t_next = self._blocks.next_latch(t_prev)
                due = ticks_ceil(t_next)
                early = due - ticks(self.lookahead_s)
                counts = None
                if early > self.env.now:  # real time only: count ahead, latch at t_next
                    yield self.env.timeout(early - self.env.now)
                    mark = w.change_event
                    counts = self._counts(t_prev, t_next)
                yield self.env.timeout(max(0, due - self.env.now))
                if counts is None or w.change_event is not mark:  # the future changed
                    counts = self._counts(t_prev, t_next)
                frames = self._sample_frames(*counts)
                gap = self.p.frame_gap_s
                if self.frame_fault is not None:
                    for i, (fid, data) in enumerate(frames):
                        self._send_at(t_next + i * gap, fid, data)
                elif self.lookahead_s or self.listeners:  # served: each frame at its time
                    yield from self._deliver_in_turn(t_next, frames)
                else:  # in virtual time: out at once, stamped; the bus hands each at its time
                    for i, (fid, data) in enumerate(frames):
                        self._put(t_next + i * gap, fid, data)
                t_prev = t_next
        except simpy.Interrupt:
            return

    def _counts(self, t0: float, t1: float) -> tuple[list[int], list[int], int, float]:
        """Gyro, string and S2^T counts of the sample [t0, t1], and t1 (from the block of
        samples being counted: instruments.isu.ieu_block)."""
        assert self._blocks is not None, "counts asked for outside a sampling"
        c = self._blocks.counts(t0, t1)
        return c[:3], c[3:9], c[9], t1

    def _sample_frames(self, g: list[int], a: list[int], timer: int,
                       t1: float) -> list[tuple[int, bytes]]:
        """The next sample's frames (held for RESEND), less any the fault injection drops."""
        seq = self.seq
        self.seq = (self.seq + 1) % 65536
        frames = sample_frames(self.codecs, seq, g, a, timer)
        self.history.append((seq, frames))
        while len(self.history) > self.history_len:
            self.history.popleft()
        if self.drop_every and seq % self.drop_every == self.drop_every - 1:
            frames = frames[1:]
        return frames

    def _deliver_in_turn(self, t1: float, frames: list[tuple[int, bytes]]
                         ) -> Generator[simpy.Event, Any, None]:
        """Put a sample's frames on the bus one frame gap apart from the latch at ``t1``,
        within the sampling's own process (one event a frame, not a process a frame). A
        STOP between two frames leaves the rest to go out on their own, as they would."""
        gap = self.p.frame_gap_s
        for i, (fid, data) in enumerate(frames):
            t = t1 + i * gap
            wait = ticks(t) - self.env.now
            try:
                if wait > 0:
                    yield self.env.timeout(wait)
            except simpy.Interrupt:
                for j, (fid_j, data_j) in enumerate(frames[i:], start=i):
                    self._send_at(t1 + j * gap, fid_j, data_j)
                raise
            self._put(t, fid, data)

    def _put(self, t: float, frame_id: int, data: bytes) -> None:
        """A frame leaves the IEU at ``t`` (now), unless the IEU is silenced."""
        if self.silent:
            return
        out = self.output
        if out and out[-1][0] > t:  # a reply due before frames already stamped ahead
            at = len(out)
            while at and out[at - 1][0] > t:
                at -= 1
            out.insert(at, (t, frame_id, data))
        else:
            out.append((t, frame_id, data))
        for cb in self.listeners:
            cb(t, frame_id, data)

    # ----- frames out -----
    def _send_now(self, name: str, sig: dict) -> None:
        """Send a reply (IEU_STATUS, IEU_ERROR) one frame gap from now, sealed by its CRC-8."""
        msg = self.db.get_message_by_name(name)
        self._send_at(self.world.now + self.p.frame_gap_s, msg.frame_id, seal(msg, sig))

    def _send_at(self, t: float, frame_id: int, data: bytes) -> None:
        fault = self.frame_fault
        if fault is not None:
            t += fault.latency_s

        def deliver() -> Generator[simpy.Event, Any, None]:
            yield self.env.timeout(max(0, ticks(t) - self.env.now))
            if self.silent:
                return
            out = data if fault is None else fault.frame(data)
            if out is not None:
                self._put(t, frame_id, out)

        self.env.process(deliver())


def sample_frames(enc: Codecs, seq: int, g: Sequence[int],
                  a: Sequence[int], timer: int) -> list[tuple[int, bytes]]:
    """The five frames (identifier, data) of sample ``seq``: counts clipped to their
    registers (``Flags`` bit 0 set if any was), then IEU_CHECK over the four count frames."""
    overflow = any(not -32768 <= x <= 32767 for x in g) or any(not 0 <= x <= 65535 for x in a)
    sigs = (
        {"Seq": seq, "Gyro1": _clip(g[0]), "Gyro2": _clip(g[1]), "Gyro3": _clip(g[2])},
        {"Seq": seq, "A1S1": _uclip(a[0]), "A1S2": _uclip(a[1]), "A2S1": _uclip(a[2])},
        {"Seq": seq, "A2S2": _uclip(a[3]), "A3S1": _uclip(a[4]), "A3S2": _uclip(a[5])},
        {"Seq": seq, "Timer": timer, "Flags": int(overflow)},
    )
    ids = enc.ids
    out = [(ids[name], enc.encode(name, sig)) for name, sig in zip(COUNT_FRAMES, sigs,
                                                                   strict=True)]
    crc = sample_crc([d for _, d in out])
    out.append((ids["IEU_CHECK"], enc.encode("IEU_CHECK", {"Seq": seq, "Crc": crc})))
    return out


def _clip(x: int) -> int:
    return max(-32768, min(32767, x))


def _uclip(x: int) -> int:
    return max(0, min(65535, x))
