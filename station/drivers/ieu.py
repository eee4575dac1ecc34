"""Driver of the IEU over python-can: commands, and samples assembled from frames by sequence.

Works on any python-can interface: ``sim`` (virtual), ``socketcand``/``slcan`` (a served
rack), ``socketcan`` (hardware). A missing frame or sample is detected from the sequence
numbers and reported, never papered over.

Recovery (``start(period, recover=True)``): a sample whose frames are missing when a later
sample's frames arrive (frames travel in order on one bus), or a sequence number skipped,
is asked for again with RESEND (IEU_COMMAND 4 with its ``Seq``); samples are still
returned strictly in sequence, each complete, and every recovery is listed in
``recoveries``. If the IEU no longer holds the sample (IEU_ERROR 5), or a resend comes back
incomplete ``MAX_RESENDS`` times, ``next_sample`` raises ``DriverError`` naming the sample:
counts are never guessed. Undecodable frames are counted in ``garbled`` and otherwise
ignored in this mode (the frame they replaced is then missing and is asked for again).
"""

from __future__ import annotations

from dataclasses import dataclass

import can
import cantools

import config
import station.links  # noqa: F401
from station.errors import DriverError, InstrumentRefused, LinkTimeout

PARTS = ("IEU_GYRO", "IEU_ACCEL_A", "IEU_ACCEL_B", "IEU_TIMER")
CMD_STOP, CMD_START, CMD_RESET, CMD_STATUS, CMD_RESEND = 0, 1, 2, 3, 4
ERR_RESEND = 5
MAX_RESENDS = 3  # resends of one sample before giving up
SEQ_MOD = 65536


def _after(a: int, b: int) -> bool:
    """Sequence number ``a`` comes after ``b`` (modulo 65536)."""
    return 0 < (a - b) % SEQ_MOD < SEQ_MOD // 2


class GarbledFrame(DriverError):
    """A frame that cannot be decoded (unknown identifier, wrong length)."""


@dataclass(frozen=True)
class IeuSample:
    seq: int
    t: float  # timestamp of the timer frame (link time)
    gyro: tuple[int, int, int]
    accel: tuple[int, int, int, int, int, int]  # A1S1, A1S2, A2S1, A2S2, A3S1, A3S2
    timer: int
    flags: int


class IeuDriver:
    def __init__(self, can_config: dict, name: str = "ieu", timeout: float = 5.0) -> None:
        self.name = name
        cfg = dict(can_config)
        self.link = f"{cfg.get('interface')}:{cfg.get('channel')}"
        self.timeout = timeout
        self.db = cantools.database.load_file(str(config.path(config.IEU_DBC)))
        try:
            self.bus = can.Bus(**cfg)
        except (can.CanError, OSError, ValueError, LookupError) as e:
            raise DriverError(name, self.link, f"cannot open CAN link: {e}") from None
        self._pending: dict[int, dict[str, dict]] = {}
        self._last_seq: int | None = None
        self.recover = False
        self._expected: int | None = None  # next sequence number to return (recover mode)
        self._resends: dict[int, int] = {}  # seq -> resends asked
        self._resend_newest: dict[int, int | None] = {}  # seq -> newest seen when last asked
        self._newest: int | None = None  # newest sequence number seen (recover mode)
        self.recoveries: list[dict] = []  # recover mode: {"seq", "missing", "resends"}
        self.garbled = 0  # recover mode: undecodable frames ignored
        self.clock = None  # set by bind_clock on OS-level links

    def bind_clock(self, clock) -> None:
        """Over OS-level links, time samples by the station clock on receipt (a hardware
        socketcand or slcan stamps in its own time base) and give the bus wall timeouts."""
        self.clock = None if clock.virtual else clock

    def close(self) -> None:
        self.bus.shutdown()

    def _send(self, command: int, period: int = 1, seq: int = 0) -> None:
        msg = self.db.get_message_by_name("IEU_COMMAND")
        try:
            data = msg.encode({"Command": command, "PeriodTicks": period, "Seq": seq})
        except cantools.database.errors.EncodeError as e:
            raise DriverError(self.name, self.link, f"cannot encode IEU_COMMAND: {e}") from None
        try:
            self.bus.send(can.Message(arbitration_id=msg.frame_id, data=data, is_extended_id=False))
        except can.CanError as e:
            raise DriverError(self.name, self.link, f"send failed: {e}") from None

    def _recv(self, timeout: float) -> tuple[str, dict, float]:
        try:
            m = self.bus.recv(timeout if self.clock is None else self.clock.link_seconds(timeout))
        except can.CanError as e:
            raise DriverError(self.name, self.link, f"receive failed: {e}") from None
        if m is None:
            raise LinkTimeout(self.name, self.link, f"no frame within {timeout:g} s")
        try:
            spec = self.db.get_message_by_frame_id(m.arbitration_id)
            sig = spec.decode(bytes(m.data), decode_choices=False)
        except (KeyError, ValueError, cantools.database.errors.DecodeError) as e:
            raise GarbledFrame(
                self.name, self.link, f"garbled frame id 0x{m.arbitration_id:03x}: {e}"
            ) from None
        t = float(m.timestamp) if self.clock is None else self.clock.now()
        return spec.name, sig, t

    def _reply(self, command: int, period: int = 1) -> dict:
        self._send(command, period)
        t_first = None
        while True:
            name, sig, t = self._recv(self.timeout)
            t_first = t if t_first is None else t_first
            if name not in ("IEU_STATUS", "IEU_ERROR") and t - t_first > self.timeout:
                # frames keep coming (a running IEU) but not the answer: it was lost
                raise LinkTimeout(self.name, self.link,
                                  f"no status reply within {self.timeout:g} s")
            if name == "IEU_STATUS":
                return sig
            if name == "IEU_ERROR":
                raise InstrumentRefused(
                    self.name,
                    self.link,
                    int(sig["Code"]),
                    f"frame 0x{int(sig['RefId']):03x} refused",
                )

    def identify(self) -> str:
        st = self._reply(3)
        return f"ISU-LAB,IEU,0,1.0 state={int(st['State'])}"

    def status(self) -> dict:
        return self._reply(3)

    def start(self, period_ticks: int, recover: bool = False) -> None:
        """Sample every ``period_ticks`` S2^T pulses; ``recover``: ask for lost samples again."""
        self._pending.clear()
        self._last_seq = None
        self._resends.clear()
        self._resend_newest.clear()
        self._newest = None
        self.recoveries = []
        self.garbled = 0
        self.recover = recover
        st = self._reply(CMD_START, period_ticks)
        self._expected = int(st["Seq"])  # the sequence number the first sample will carry

    def stop(self) -> None:
        self._reply(0)

    def reset(self) -> None:
        self._reply(2)

    def resend(self, seq: int) -> None:
        """Ask the IEU for the frames of sample ``seq`` again (answered by the frames)."""
        self._send(CMD_RESEND, 1, seq)

    def next_sample(self, timeout: float | None = None) -> IeuSample:
        """The next complete sample; raises DriverError on a lost frame or sample.

        In recover mode (``start(..., recover=True)``) lost frames are asked for again.
        """
        wait = self.timeout if timeout is None else timeout
        if self.recover:
            return self._next_recovering(wait)
        while True:
            name, sig, t = self._recv(wait)
            if name not in PARTS:
                continue
            seq = int(sig["Seq"])
            older = [s for s in self._pending if s != seq]
            if older:
                s = min(older)
                have = sorted(self._pending[s])
                self._pending.clear()
                raise DriverError(
                    self.name, self.link, f"lost frame(s) of sample {s}: received only {have}"
                )
            parts = self._pending.setdefault(seq, {})
            parts[name] = sig | {"_t": t}
            if len(parts) == len(PARTS):
                del self._pending[seq]
                if self._last_seq is not None and seq != (self._last_seq + 1) % 65536:
                    lost = (seq - self._last_seq - 1) % 65536
                    self._last_seq = seq
                    raise DriverError(
                        self.name, self.link, f"lost {lost} sample(s) before sequence {seq}"
                    )
                self._last_seq = seq
                return _sample(seq, parts)

    def _next_recovering(self, wait: float) -> IeuSample:
        exp = self._expected
        if exp is None:
            raise DriverError(self.name, self.link, "recover mode needs start() first")
        while True:
            parts = self._pending.get(exp, {})
            if len(parts) == len(PARTS):
                del self._pending[exp]
                self._resends.pop(exp, None)
                self._resend_newest.pop(exp, None)
                self._expected = (exp + 1) % SEQ_MOD
                return _sample(exp, parts)
            if self._newest is not None and _after(self._newest, exp):
                self._ask_again(exp, parts)
            try:
                name, sig, t = self._recv(wait)
            except GarbledFrame:  # undecodable: the frame it replaced is asked for again
                self.garbled += 1
                continue
            if name == "IEU_ERROR":
                if int(sig["Code"]) == ERR_RESEND:
                    have = sorted(self._pending.get(exp, {}))
                    raise DriverError(
                        self.name, self.link,
                        f"sample {exp} lost (received only {have}) and the IEU no longer "
                        "holds it (RESEND refused, code 5)",
                    )
                raise InstrumentRefused(
                    self.name, self.link, int(sig["Code"]),
                    f"frame 0x{int(sig['RefId']):03x} refused",
                )
            if name not in PARTS:
                continue
            seq = int(sig["Seq"])
            if seq != exp and not _after(seq, exp):
                continue  # a duplicate of a sample already returned
            if self._newest is None or _after(seq, self._newest):
                self._newest = seq
            self._pending.setdefault(seq, {}).setdefault(name, sig | {"_t": t})

    def _ask_again(self, seq: int, parts: dict) -> None:
        """Sample ``seq`` is incomplete while a later one has begun: RESEND it (bounded)."""
        n = self._resends.get(seq, 0)
        pending_resend = n > 0 and self._resend_newest.get(seq) == self._newest
        if pending_resend:
            return  # asked already; nothing newer has arrived since
        if n >= MAX_RESENDS:
            raise DriverError(
                self.name, self.link,
                f"sample {seq} still incomplete after {n} resends (received only "
                f"{sorted(parts)})",
            )
        self._resends[seq] = n + 1
        self._resend_newest[seq] = self._newest
        rec = {"seq": seq, "missing": [p for p in PARTS if p not in parts], "resends": n + 1}
        self.recoveries.append(rec)
        self.resend(seq)


def _sample(seq: int, parts: dict[str, dict]) -> IeuSample:
    g, a, b, tm = (parts[p] for p in PARTS)
    return IeuSample(
        seq=seq,
        t=tm["_t"],
        gyro=(int(g["Gyro1"]), int(g["Gyro2"]), int(g["Gyro3"])),
        accel=(
            int(a["A1S1"]),
            int(a["A1S2"]),
            int(a["A2S1"]),
            int(b["A2S2"]),
            int(b["A3S1"]),
            int(b["A3S2"]),
        ),
        timer=int(tm["Timer"]),
        flags=int(tm["Flags"]),
    )
