"""Driver of the IEU over python-can: commands, and samples assembled from frames by sequence.

Works on any python-can interface: ``sim`` (virtual), ``socketcand``/``slcan`` (a served
rack), ``socketcan`` (hardware). A missing frame or sample is detected from the sequence
numbers and reported, never papered over.
"""

from __future__ import annotations

from dataclasses import dataclass

import can
import cantools

import config
import station.links  # noqa: F401
from station.errors import DriverError, InstrumentRefused, LinkTimeout

PARTS = ("IEU_GYRO", "IEU_ACCEL_A", "IEU_ACCEL_B", "IEU_TIMER")


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

    def close(self) -> None:
        self.bus.shutdown()

    def _send(self, command: int, period: int = 1) -> None:
        msg = self.db.get_message_by_name("IEU_COMMAND")
        try:
            data = msg.encode({"Command": command, "PeriodTicks": period})
        except cantools.database.errors.EncodeError as e:
            raise DriverError(self.name, self.link, f"cannot encode IEU_COMMAND: {e}") from None
        try:
            self.bus.send(can.Message(arbitration_id=msg.frame_id, data=data, is_extended_id=False))
        except can.CanError as e:
            raise DriverError(self.name, self.link, f"send failed: {e}") from None

    def _recv(self, timeout: float) -> tuple[str, dict, float]:
        try:
            m = self.bus.recv(timeout)
        except can.CanError as e:
            raise DriverError(self.name, self.link, f"receive failed: {e}") from None
        if m is None:
            raise LinkTimeout(self.name, self.link, f"no frame within {timeout:g} s")
        try:
            spec = self.db.get_message_by_frame_id(m.arbitration_id)
            sig = spec.decode(bytes(m.data), decode_choices=False)
        except (KeyError, ValueError, cantools.database.errors.DecodeError) as e:
            raise DriverError(
                self.name, self.link, f"garbled frame id 0x{m.arbitration_id:03x}: {e}"
            ) from None
        return spec.name, sig, float(m.timestamp)

    def _reply(self, command: int, period: int = 1) -> dict:
        self._send(command, period)
        while True:
            name, sig, _ = self._recv(self.timeout)
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

    def start(self, period_ticks: int) -> None:
        """Sample every ``period_ticks`` S2^T pulses."""
        self._pending.clear()
        self._last_seq = None
        self._reply(1, period_ticks)

    def stop(self) -> None:
        self._reply(0)

    def reset(self) -> None:
        self._reply(2)

    def next_sample(self, timeout: float | None = None) -> IeuSample:
        """The next complete sample; raises DriverError on a lost frame or sample."""
        wait = self.timeout if timeout is None else timeout
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
