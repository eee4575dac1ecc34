"""Interface electronics unit (CAN): accumulating registers sampled on S2^T pulses.

On START the IEU latches its registers on every PeriodTicks-th S2^T pulse and sends one
sample as four frames (gyro, accelerometer A and B, timer) sharing a sequence number.
Registers are read and cleared at the same edge, so consecutive samples telescope: no
count is ever lost between reads. Frames are defined in config/ieu.dbc.

The IEU keeps the frames of its last ``history_len`` samples. RESEND (Command 4, with the
sample's sequence number in the command's ``Seq``) sends that sample's four frames again,
exactly as first sent; it is the host's way of recovering a frame lost on the bus. A
sample no longer (or never) held is refused with IEU_ERROR code 5. A resend is answered by
the frames themselves, not by IEU_STATUS, so it never disturbs the command/status pairing.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING

import cantools

import config
from instruments.params import IeuParams
from sim.timebase import ticks, ticks_ceil
from sim.world import World

if TYPE_CHECKING:
    from instruments.faults import FrameFault

GYRO_LINES = ("G1", "G2", "G3")
ACCEL_LINES = ("A1S1", "A1S2", "A2S1", "A2S2", "A3S1", "A3S2")
CMD_STOP, CMD_START, CMD_RESET, CMD_STATUS, CMD_RESEND = 0, 1, 2, 3, 4
ERR_ID, ERR_DLC, ERR_CMD, ERR_PERIOD, ERR_RESEND = 1, 2, 3, 4, 5
HISTORY_LEN = 16  # samples held for RESEND (1.6 s at 1000 S2^T pulses, 0.1 s, a sample)


def load_dbc() -> cantools.database.Database:
    return cantools.database.load_file(str(config.path(config.IEU_DBC)))


class Ieu:
    ident = "ISU-LAB,IEU,0,1.0"

    def __init__(self, name: str, world: World, p: IeuParams) -> None:
        self.name = name
        self.world = world
        self.env = world.env
        self.p = p
        self.db = load_dbc()
        self.output: deque[tuple[float, int, bytes]] = deque()
        self.listeners: list[Callable[[float, int, bytes], None]] = []
        self.running = False
        self.period = 1000
        self.seq = 0
        self.error_code = 0
        self._proc = None
        self.drop_every = 0  # fault injection: drop every n-th sample's gyro frame
        self.silent = False
        # real time only: count a sample this long (simulated s) before it is latched, so
        # the frames leave on time; a world change in between (table command, re-patch)
        # makes it count again at the latch instant. Zero in virtual time.
        self.lookahead_s = 0.0
        self.frame_fault: FrameFault | None = None  # fault injection: delayed, lost, altered frames
        self.history_len = HISTORY_LEN  # fault injection: 0 makes every RESEND fail
        self.history: deque[tuple[int, list[tuple[str, dict]]]] = deque()

    # ----- frames in -----
    def receive_frame(self, arbitration_id: int, data: bytes) -> None:
        try:
            msg = self.db.get_message_by_frame_id(arbitration_id)
        except KeyError:
            return self._refuse(ERR_ID, arbitration_id)
        if msg.name != "IEU_COMMAND":
            return self._refuse(ERR_ID, arbitration_id)
        if len(data) != msg.length:
            return self._refuse(ERR_DLC, arbitration_id)
        sig = msg.decode(bytes(data), decode_choices=False)
        cmd = int(sig["Command"])
        if cmd == CMD_START:
            period = int(sig["PeriodTicks"])
            if period < 1 or period * self.world.oscillator.s2_nominal > self.p.max_period_s:
                return self._refuse(ERR_PERIOD, arbitration_id)
            self._stop()
            self.period = period
            self.running = True
            self._proc = self.env.process(self._sample_loop())
        elif cmd == CMD_STOP:
            self._stop()
        elif cmd == CMD_RESET:
            self._stop()
            self.seq = 0
            self.history.clear()
        elif cmd == CMD_RESEND:
            return self._resend(int(sig["Seq"]), arbitration_id)
        elif cmd != CMD_STATUS:
            return self._refuse(ERR_CMD, arbitration_id)
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
        for i, (name, sig) in enumerate(held[seq], start=1):
            self._send_at(t + i * self.p.frame_gap_s, name, sig)

    def _refuse(self, code: int, ref: int) -> None:
        self.error_code = code
        self._send_now("IEU_ERROR", {"Code": code, "RefId": ref & 0x7FF})

    def _stop(self) -> None:
        self.running = False
        if self._proc is not None and self._proc.is_alive:
            self._proc.interrupt()
        self._proc = None

    # ----- sampling -----
    def _sample_loop(self):
        import simpy

        w = self.world
        s2 = w.line("OSC2")
        try:
            t_prev = s2.edge_after(w.now, 1)
            yield self.env.timeout(max(0, ticks_ceil(t_prev) - self.env.now))
            while self.running:
                t_next = s2.edge_after(t_prev, self.period)
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
                self._emit_sample(*counts)
                t_prev = t_next
        except simpy.Interrupt:
            return

    def _counts(self, t0: float, t1: float) -> tuple[list[int], list[int], int, float]:
        """Gyro, string and S2^T counts of the sample [t0, t1], and t1."""
        w = self.world
        g = [w.line(n).count(t0, t1) for n in GYRO_LINES]
        a = [w.line(n).count(t0, t1) for n in ACCEL_LINES]
        return g, a, w.line("OSC2").count(t0, t1), t1

    def _emit_sample(self, g: list[int], a: list[int], timer: int, t1: float) -> None:
        overflow = any(abs(x) > 32767 for x in g) or any(x > 65535 for x in a)
        seq = self.seq
        self.seq = (self.seq + 1) % 65536
        frames = [
            (
                "IEU_GYRO",
                {"Seq": seq, "Gyro1": _clip(g[0]), "Gyro2": _clip(g[1]), "Gyro3": _clip(g[2])},
            ),
            (
                "IEU_ACCEL_A",
                {"Seq": seq, "A1S1": _uclip(a[0]), "A1S2": _uclip(a[1]), "A2S1": _uclip(a[2])},
            ),
            (
                "IEU_ACCEL_B",
                {"Seq": seq, "A2S2": _uclip(a[3]), "A3S1": _uclip(a[4]), "A3S2": _uclip(a[5])},
            ),
            ("IEU_TIMER", {"Seq": seq, "Timer": timer, "Flags": int(overflow)}),
        ]
        self.history.append((seq, frames))
        while len(self.history) > self.history_len:
            self.history.popleft()
        if self.drop_every and seq % self.drop_every == self.drop_every - 1:
            frames = frames[1:]
        for i, (name, sig) in enumerate(frames):
            self._send_at(t1 + i * self.p.frame_gap_s, name, sig)

    # ----- frames out -----
    def _send_now(self, name: str, sig: dict) -> None:
        self._send_at(self.world.now + self.p.frame_gap_s, name, sig)

    def _send_at(self, t: float, name: str, sig: dict) -> None:
        msg = self.db.get_message_by_name(name)
        data = msg.encode(sig)
        fault = self.frame_fault
        if fault is not None:
            t += fault.latency_s

        def deliver():
            yield self.env.timeout(max(0, ticks(t) - self.env.now))
            if self.silent:
                return
            out = data if fault is None else fault.frame(data)
            if out is None:
                return
            self.output.append((t, msg.frame_id, out))
            for cb in self.listeners:
                cb(t, msg.frame_id, out)

        self.env.process(deliver())


def _clip(x: int) -> int:
    return max(-32768, min(32767, x))


def _uclip(x: int) -> int:
    return max(0, min(65535, x))
