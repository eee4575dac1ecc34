"""Driver of the IEU over python-can: commands, and samples assembled from frames by sequence.

Works on any python-can interface: ``sim`` (virtual), ``socketcand``/``slcan`` (a served
rack), ``socketcan`` (hardware). Every frame from the IEU is checked end to end (the DBC's
``Crc`` signals, table-driven in `crc.py`): a sample is returned only when its five frames
are present and the CRC-32C of its closing IEU_CHECK matches the four count frames; an
IEU_STATUS or IEU_ERROR only when its CRC-8 matches. A frame that fails its check is a lost
frame: never used, never papered over.

Commands (``start``, ``stop``, ``reset``, ``status``) wait for their IEU_STATUS, and check
that it echoes the command (state, period, sequence). A status lost or failing its check
while the IEU goes on sending frames makes the driver send the command again, up to
``MAX_TRIES`` times in all; a silent link raises ``LinkTimeout`` at once.

Recovery (``start(period, recover=True)``): a sample whose frames are missing when a later
sample has been received whole, or whose check fails, is asked for again with RESEND
(IEU_COMMAND 4 with its ``Seq``); samples are still returned strictly in sequence, each
complete and verified, and every recovery is listed in ``recoveries``. If the IEU no longer
holds the sample (IEU_ERROR 5), or it is still incomplete or failing its check after
``MAX_RESENDS`` resends, ``next_sample`` raises ``DriverError`` naming the sample: counts
are never guessed. Undecodable frames are counted in ``garbled`` and otherwise ignored in
this mode (the frame they replaced is then missing and is asked for again).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import can
import cantools

import station.links  # noqa: F401
from config.dbc import Codecs, codecs
from station.clock import Clock
from station.drivers.isu.crc import crc8_autosar, crc32c
from station.errors import DriverError, InstrumentRefused, LinkTimeout

COUNT_PARTS = ("IEU_GYRO", "IEU_ACCEL_A", "IEU_ACCEL_B", "IEU_TIMER")
PARTS = (*COUNT_PARTS, "IEU_CHECK")  # the five frames of one sample, in the order sent
CMD_STOP, CMD_START, CMD_RESET, CMD_STATUS, CMD_RESEND = 0, 1, 2, 3, 4
ERR_RESEND = 5
MAX_RESENDS = 3  # resends of one sample before giving up
MAX_TRIES = 3  # sends of one command whose status is lost or fails its check
SEQ_MOD = 65536
HELD = 16  # samples the IEU holds for RESEND (config/ieu.dbc)
WINDOW = 2 * HELD  # sequence numbers ahead of the expected one worth keeping frames for
# frames received while one sample stays unresolved before the driver gives up on it: by
# then the IEU has sent more samples than it holds, so the sample cannot come back
PATIENCE_FRAMES = (HELD + 2) * len(PARTS)
# a resend is answered at once; sampling may still deliver this many later samples (latched
# before the RESEND reached the IEU) before its frames: only then is it taken as lost
RESEND_SLACK = 2
MAX_PERIOD = 2**32 - 1
STATUS_FIELDS = ("State", "PeriodTicks", "Seq", "ErrorCode")  # what status() reports
DRAIN_LIMIT = 100_000  # frames discarded before a command, at most


def _after(a: int, b: int) -> bool:
    """Sequence number ``a`` comes after ``b`` (modulo 65536)."""
    return 0 < (a - b) % SEQ_MOD < SEQ_MOD // 2


class GarbledFrame(DriverError):
    """A frame that cannot be decoded (unknown identifier, wrong length)."""


class FailedCheck(GarbledFrame):
    """An IEU_STATUS or IEU_ERROR whose CRC-8 does not match its bytes."""


@dataclass(frozen=True)
class IeuSample:
    seq: int
    t: float  # timestamp of the timer frame (link time)
    gyro: tuple[int, int, int]
    accel: tuple[int, int, int, int, int, int]  # A1S1, A1S2, A2S1, A2S2, A3S1, A3S2
    timer: int
    flags: int


@dataclass(frozen=True)
class Frame:
    """One decoded IEU frame: message name, integer signals, raw data, link time."""

    name: str
    sig: dict[str, int]
    data: bytes
    t: float


def crc8_ok(msg: cantools.database.can.Message, data: bytes, crc: int) -> bool:
    """The CRC-8/AUTOSAR of the identifier and the frame's other bytes equals ``crc``."""
    at = msg.get_signal_by_name("Crc").start // 8
    protected = msg.frame_id.to_bytes(2, "little") + data[:at] + data[at + 1:]
    return crc8_autosar(protected) == crc


def decode_frame(dec: Codecs, name: str, link: str,
                 arbitration_id: object, data: object, t: float) -> Frame:
    """Decode one received frame with the DBC; ``GarbledFrame`` for anything that is not an
    IEU frame of the right length, ``FailedCheck`` for a reply failing its CRC-8."""
    try:
        fid = int(arbitration_id)  # type: ignore[call-overload]  # any object; caught below
        raw = bytes(data)  # type: ignore[call-overload]  # any object; caught below
        msg, length = dec.by_id[fid]
    except (KeyError, TypeError, ValueError, OverflowError):
        raise GarbledFrame(name, link, f"garbled frame id {_hex_id(arbitration_id)}: "
                                       "not an IEU frame") from None
    if len(raw) != length:
        raise GarbledFrame(name, link, f"garbled frame id 0x{fid:03x}: {len(raw)} bytes, "
                                       f"{msg} has {length}")
    try:
        ints = dec.decode(msg, raw)
    except (ValueError, TypeError, cantools.database.errors.DecodeError) as e:
        raise GarbledFrame(name, link, f"garbled frame id 0x{fid:03x}: {e}") from None
    if "Crc" in ints and msg != "IEU_CHECK" and not crc8_ok(
            dec.db.get_message_by_name(msg), raw, ints["Crc"]):
        raise FailedCheck(name, link, f"{msg} failed its CRC-8 check")
    return Frame(msg, ints, raw, t)


def _hex_id(x: object) -> str:
    return f"0x{x:03x}" if isinstance(x, int) else repr(x)


@dataclass
class _Group:
    """The frames received so far for one sequence number."""

    frames: dict[str, Frame] = field(default_factory=dict)
    conflict: bool = False  # two different frames of the same kind arrived
    crc_ok: bool | None = None  # the CRC-32C check, once the group is complete

    def add(self, f: Frame) -> None:
        old = self.frames.get(f.name)
        if old is None:
            self.frames[f.name] = f
        elif old.data != f.data:
            self.conflict = True

    @property
    def complete(self) -> bool:
        return len(self.frames) == len(PARTS)

    def missing(self) -> list[str]:
        return [p for p in PARTS if p not in self.frames]

    def verified(self, seq: int) -> IeuSample | None:
        """The sample if complete, unconflicted and matching its CRC-32C; else None."""
        if not self.complete or self.conflict:
            return None
        if self.crc_ok is None:  # a complete group's frames never change: check it once
            crc = crc32c(b"".join(self.frames[p].data for p in COUNT_PARTS))
            self.crc_ok = crc == self.frames["IEU_CHECK"].sig["Crc"]
        if not self.crc_ok:
            return None
        return _sample(seq, self.frames)


class SampleAssembler:
    """Frames in, verified samples out, strictly in sequence from ``expected``.

    Frames are grouped by their ``Seq``; only sequence numbers from ``expected`` to
    ``expected + WINDOW`` are kept (others are old duplicates or altered numbers).
    Pure bookkeeping: the driver decides when to ask for a resend.
    """

    def __init__(self, expected: int) -> None:
        self.expected = expected % SEQ_MOD
        self.groups: dict[int, _Group] = {}
        self.newest_verified: int | None = None  # latest sample received whole and intact
        self.strays = 0  # frames outside the window (old duplicates, altered Seq)

    def add(self, f: Frame) -> None:
        seq = f.sig["Seq"]
        if (seq - self.expected) % SEQ_MOD >= WINDOW:
            self.strays += 1
            return
        g = self.groups.setdefault(seq, _Group())
        g.add(f)
        if f.name == "IEU_CHECK" or g.complete:
            if g.verified(seq) is not None and (
                    self.newest_verified is None or _after(seq, self.newest_verified)):
                self.newest_verified = seq

    def group(self) -> _Group:
        return self.groups.get(self.expected, _Group())

    def take(self) -> IeuSample | None:
        """The expected sample if it is here whole and intact (and move on past it)."""
        s = self.group().verified(self.expected)
        if s is not None:
            del self.groups[self.expected]
            self.expected = (self.expected + 1) % SEQ_MOD
        return s

    def take_whole(self, frames: dict[str, Frame]) -> IeuSample | None:
        """The expected sample from its five frames received in order, none kept for it
        yet: checked as any group is, and the assembler moved past it; None (nothing
        changed) if they fail the check."""
        seq = self.expected
        s = _Group(frames=frames).verified(seq)
        if s is not None:
            if self.newest_verified is None or _after(seq, self.newest_verified):
                self.newest_verified = seq
            self.expected = (seq + 1) % SEQ_MOD
        return s

    def failed(self) -> bool:
        """The expected sample is complete but conflicted or failing its CRC-32C."""
        g = self.group()
        return g.complete and g.verified(self.expected) is None

    def later_verified(self, than: int) -> bool:
        """A sample after ``than`` has been received whole and intact."""
        return self.newest_verified is not None and _after(self.newest_verified, than)

    def forget(self) -> None:
        """Drop what was received for the expected sample (before it is sent again)."""
        self.groups.pop(self.expected, None)


class IeuDriver:
    def __init__(self, name: str, can_config: dict, clock: Clock | None = None,
                 timeout: float = 5.0) -> None:
        """The drivers' convention (``SerialDriver``), with python-can's bus configuration
        for the link."""
        self.name = name
        cfg = dict(can_config)
        self.link = f"{cfg.get('interface')}:{cfg.get('channel')}"
        self.timeout = timeout
        self.codecs = codecs()
        self.db = self.codecs.db
        try:
            self.bus = can.Bus(**cfg)
        except (can.CanError, OSError, ValueError, LookupError, TypeError) as e:
            raise DriverError(name, self.link, f"cannot open CAN link: {e}") from None
        self.recover = False
        self._asm = SampleAssembler(0)  # recover mode: frames grouped by sequence number
        self._plain: dict[int, _Group] = {}  # plain mode: frames by sequence number
        self._last_seq: int | None = None  # plain mode: the last sample returned
        self._resends: dict[int, int] = {}  # seq -> resends asked
        self._asked_at: dict[int, int] = {}  # seq -> newest verified sample when last asked
        self._waited = 0  # frames received while the expected sample stays unresolved
        self.recoveries: list[dict] = []  # recover mode: {"seq", "missing", "failed_check",
        #                                   "resends"}
        self.garbled = 0  # recover mode: undecodable frames ignored
        self.failed_checks = 0  # frames or samples that failed their CRC (every mode)
        self.discarded = 0  # frames that answered nothing: stale replies, old samples
        self.clock: Clock | None = None  # the station clock on OS-level links only
        # called with every frame sent (``is_rx`` False, stamped with the station clock) and
        # received (``is_rx`` True), e.g. to log the run's CAN traffic; None: no hook
        self.frame_hook: Callable[[can.Message], None] | None = None
        self._stamp: Clock | None = clock
        if clock is not None:
            self.bind_clock(clock)

    def bind_clock(self, clock: Clock) -> None:
        """Over OS-level links, time samples by the station clock on receipt (a hardware
        socketcand or slcan stamps in its own time base) and give the bus wall timeouts."""
        self.clock = None if clock.virtual else clock
        self._stamp = clock

    def close(self) -> None:
        self.bus.shutdown()

    def _error(self, message: str) -> DriverError:
        return DriverError(self.name, self.link, message)

    def _send(self, command: int, period: int = 0, seq: int = 0) -> None:
        msg = self.db.get_message_by_name("IEU_COMMAND")
        try:
            data = msg.encode({"Command": command, "PeriodTicks": period, "Seq": seq})
        except (cantools.database.errors.EncodeError, ValueError, TypeError) as e:
            raise self._error(f"cannot encode IEU_COMMAND: {e}") from None
        m = can.Message(arbitration_id=msg.frame_id, data=data, is_extended_id=False,
                        is_rx=False)
        try:
            self.bus.send(m)
        except can.CanError as e:
            raise self._error(f"send failed: {e}") from None
        if self.frame_hook is not None:
            m.timestamp = self._stamp.now() if self._stamp is not None else 0.0
            self.frame_hook(m)

    def _bus_recv(self, timeout: float) -> can.Message | None:
        """One frame from the bus (None: none within ``timeout``), shown to the hook."""
        try:
            m = self.bus.recv(timeout)
        except can.CanError as e:
            raise self._error(f"receive failed: {e}") from None
        if m is not None and self.frame_hook is not None:
            m.is_rx = True
            if self.clock is not None:  # an OS-level link: the station clock's time
                m.timestamp = self.clock.now()
            self.frame_hook(m)
        return m

    def _recv(self, timeout: float) -> Frame:
        m = self._bus_recv(timeout if self.clock is None else self.clock.link_seconds(timeout))
        if m is None:
            raise LinkTimeout(self.name, self.link, f"no frame within {timeout:g} s")
        t = float(m.timestamp) if self.clock is None else self.clock.now()
        return decode_frame(self.codecs, self.name, self.link, m.arbitration_id, m.data, t)

    # ----- commands -----
    def _drain(self) -> None:
        """Discard frames received before a command (stale replies, samples of a sampling
        that is over): none of them can answer it. One that is no IEU frame at all is
        still reported (``GarbledFrame``)."""
        for _ in range(DRAIN_LIMIT):
            m = self._bus_recv(0.0)
            if m is None:
                return
            self.discarded += 1
            try:
                decode_frame(self.codecs, self.name, self.link, m.arbitration_id, m.data, 0.0)
            except FailedCheck:
                self.failed_checks += 1

    def _reply(self, command: int, period: int = 0) -> dict[str, int]:
        """Send ``command`` and return the IEU_STATUS that answers it. The command is sent
        again (MAX_TRIES sends in all) when its status is lost among other frames, fails its
        CRC-8, or does not echo the command."""
        self._drain()
        why, lost = "", False
        for _ in range(MAX_TRIES):
            self._send(command, period)
            t_first = None
            wrong = False
            while True:
                try:
                    f = self._recv(self.timeout)
                except FailedCheck as e:
                    self.failed_checks += 1
                    why, lost = e.detail, False
                    break  # the reply (status or refusal) is lost: ask again
                except LinkTimeout:
                    if not wrong:
                        raise  # a silent link: nothing to ask again
                    break
                t_first = f.t if t_first is None else t_first
                if f.name == "IEU_STATUS":
                    bad = _not_echoed(command, period, f.sig)
                    if not bad:
                        return {k: f.sig[k] for k in STATUS_FIELDS}
                    self.discarded += 1  # stale, or altered: wait for the right one
                    why, lost, wrong = f"IEU_STATUS does not echo it ({bad})", False, True
                    continue
                if f.name == "IEU_ERROR":
                    raise InstrumentRefused(
                        self.name, self.link, f.sig["Code"],
                        f"frame 0x{f.sig['RefId']:03x} refused",
                    )
                if f.t - t_first > self.timeout:
                    # frames keep coming (a running IEU) but not the answer: it was lost
                    if not wrong:
                        why, lost = f"no status reply within {self.timeout:g} s", True
                    break
        msg = f"command {command}: {why} ({MAX_TRIES} tries)"
        raise (LinkTimeout(self.name, self.link, msg) if lost else self._error(msg))

    def identify(self) -> str:
        st = self._reply(CMD_STATUS)
        return f"ISU-LAB,IEU,0,1.0 state={st['State']}"

    def status(self) -> dict[str, int]:
        return self._reply(CMD_STATUS)

    def start(self, period_ticks: int, recover: bool = False) -> None:
        """Sample every ``period_ticks`` S2^T pulses; ``recover``: ask for lost samples again."""
        if not isinstance(period_ticks, int) or not 1 <= period_ticks <= MAX_PERIOD:
            raise self._error(f"cannot encode IEU_COMMAND: PeriodTicks {period_ticks!r} "
                              f"outside [1, {MAX_PERIOD}]")
        self._plain.clear()
        self._last_seq = None
        self._resends.clear()
        self._asked_at.clear()
        self._waited = 0
        self.recoveries = []
        self.garbled = 0
        self.failed_checks = 0
        self.recover = recover
        st = self._reply(CMD_START, period_ticks)
        self._asm = SampleAssembler(st["Seq"])  # the number the first sample will carry

    def stop(self) -> None:
        self._reply(CMD_STOP)

    def reset(self) -> None:
        self._reply(CMD_RESET)

    def resend(self, seq: int) -> None:
        """Ask the IEU for the frames of sample ``seq`` again (answered by the frames)."""
        self._send(CMD_RESEND, 0, seq)

    # ----- samples -----
    def next_sample(self, timeout: float | None = None) -> IeuSample:
        """The next complete, verified sample; raises DriverError on a lost or failed one.

        In recover mode (``start(..., recover=True)``) such samples are asked for again.
        """
        wait = self.timeout if timeout is None else timeout
        if self.recover:
            return self._next_recovering(wait)
        return self._next_plain(wait)

    def _next_plain(self, wait: float) -> IeuSample:
        groups = self._plain
        while True:
            f = self._recv(wait)
            if f.name not in PARTS:
                continue
            seq = f.sig["Seq"]
            older = [s for s in groups if s != seq]
            if older:  # frames travel in order: a sample begun before this one is short
                s = min(older, key=lambda x: (x - seq) % SEQ_MOD)
                have = sorted(groups[s].frames)
                for x in older:
                    del groups[x]
                groups.setdefault(seq, _Group()).add(f)
                self._last_seq = s  # reported here, not again as a gap in the sequence
                raise self._error(f"lost frame(s) of sample {s}: received only {have}")
            g = groups.setdefault(seq, _Group())
            g.add(f)
            if not g.complete:
                continue
            del groups[seq]
            sample = g.verified(seq)
            last, self._last_seq = self._last_seq, seq
            if sample is None:
                self.failed_checks += 1
                raise self._error(f"sample {seq} failed its CRC-32C check")
            if last is not None and seq != (last + 1) % SEQ_MOD:
                lost = (seq - last - 1) % SEQ_MOD
                raise self._error(f"lost {lost} sample(s) before sequence {seq}")
            return sample

    def _next_recovering(self, wait: float) -> IeuSample:
        asm = self._asm
        if not asm.groups and not self._waited:
            sample = self._in_order(wait)
            if sample is not None:
                return sample
        while True:
            exp = asm.expected
            sample = asm.take()
            if sample is not None:
                return self._received(exp, sample)
            if asm.failed():
                self.failed_checks += 1
                self._ask_again(exp, failed=True)
            elif self._due(exp):
                self._ask_again(exp, failed=False)
            if self._waited > PATIENCE_FRAMES:
                raise self._error(
                    f"sample {exp} not received whole after {self._waited} frames "
                    f"({self._resends.get(exp, 0)} resends); received only "
                    f"{sorted(asm.group().frames)}")
            try:
                f = self._recv(wait)
            except GarbledFrame as e:  # undecodable: the frame it replaced is asked for again
                self._garbled(e)
                continue
            self._absorb(f)

    def _received(self, seq: int, sample: IeuSample) -> IeuSample:
        """Sample ``seq`` received whole: nothing more to ask for it."""
        self._resends.pop(seq, None)
        self._asked_at.pop(seq, None)
        self._waited = 0
        return sample

    def _garbled(self, e: GarbledFrame) -> None:
        """An undecodable frame (or one failing its CRC-8) counted in recover mode."""
        self.garbled += 1
        self.failed_checks += isinstance(e, FailedCheck)
        self._waited += 1

    def _in_order(self, wait: float) -> IeuSample | None:
        """The expected sample when its five frames come next, in order and intact (the
        common case, checked frame by frame at little cost); None as soon as a frame does
        not fit, with what was received handed to the assembler (``_absorb``), so the
        recovering loop goes on exactly as if it had received them itself."""
        asm = self._asm
        exp = asm.expected
        got: list[Frame] = []
        for part in PARTS:
            try:
                f = self._recv(wait)
            except LinkTimeout:
                for g in got:
                    self._absorb(g)
                raise
            except GarbledFrame as e:
                for g in got:
                    self._absorb(g)
                self._garbled(e)
                return None
            if f.name != part or f.sig["Seq"] != exp:
                for g in (*got, f):
                    self._absorb(g)
                return None
            got.append(f)
        sample = asm.take_whole(dict(zip(PARTS, got, strict=True)))
        if sample is None:  # failing its CRC-32C: the loop asks for it again
            for g in got:
                self._absorb(g)
            return None
        return self._received(exp, sample)

    def _absorb(self, f: Frame) -> None:
        """One frame received in recover mode: a refusal raises, a sample's part is kept."""
        self._waited += 1
        if f.name == "IEU_ERROR":
            exp = self._asm.expected
            if f.sig["Code"] == ERR_RESEND:
                raise self._error(
                    f"sample {exp} lost (received only {sorted(self._asm.group().frames)}) "
                    "and the IEU no longer holds it (RESEND refused, code 5)")
            raise InstrumentRefused(self.name, self.link, f.sig["Code"],
                                    f"frame 0x{f.sig['RefId']:03x} refused")
        if f.name in PARTS:
            self._asm.add(f)

    def _due(self, seq: int) -> bool:
        """Sample ``seq`` is incomplete while a later sample has come whole (first ask), or
        more than RESEND_SLACK later samples have come since the last ask (the resend is
        lost too)."""
        asked = self._asked_at.get(seq)
        if asked is None:
            return self._asm.later_verified(seq)
        return self._asm.later_verified((asked + RESEND_SLACK) % SEQ_MOD)

    def _ask_again(self, seq: int, failed: bool) -> None:
        """RESEND sample ``seq`` (bounded), dropping what was received of it."""
        n = self._resends.get(seq, 0)
        missing = self._asm.group().missing()
        if n >= MAX_RESENDS:
            if failed:
                raise self._error(f"sample {seq} failed its CRC-32C check after {n} resends")
            raise self._error(f"sample {seq} still incomplete after {n} resends (received "
                              f"only {sorted(self._asm.group().frames)})")
        self._resends[seq] = n + 1
        newest = self._asm.newest_verified
        self._asked_at[seq] = seq if newest is None or not _after(newest, seq) else newest
        self.recoveries.append({"seq": seq, "missing": missing, "failed_check": failed,
                                "resends": n + 1})
        self._asm.forget()
        self.resend(seq)


def _not_echoed(command: int, period: int, st: dict[str, int]) -> str:
    """What in a status contradicts the command it should answer ('' if nothing)."""
    want: dict[str, int] = {}
    if command == CMD_START:
        want = {"State": 1, "PeriodTicks": period}
    elif command == CMD_STOP:
        want = {"State": 0}
    elif command == CMD_RESET:
        want = {"State": 0, "Seq": 0}
    return ", ".join(f"{k} {st[k]}, not {v}" for k, v in want.items() if st[k] != v)


def _sample(seq: int, parts: dict[str, Frame]) -> IeuSample:
    g, a, b, tm = (parts[p].sig for p in COUNT_PARTS)
    return IeuSample(
        seq=seq,
        t=parts["IEU_TIMER"].t,
        gyro=(g["Gyro1"], g["Gyro2"], g["Gyro3"]),
        accel=(a["A1S1"], a["A1S2"], a["A2S1"], b["A2S2"], b["A3S1"], b["A3S2"]),
        timer=tm["Timer"],
        flags=tm["Flags"],
    )
