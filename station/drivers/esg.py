"""Drivers of the ESG laboratory (report 004): data processor, dividing head, turntable,
theodolite and gyro control console.

``ProcessorDriver.lines(k)`` is the only reader of the processor's data lines. Every line
it returns is either a :class:`DataLine` that passed the Appendix-A checks or a
:class:`BadLine` saying what was wrong with it; a garbled data line never raises, and the
digits of a bad line are never parsed into counts. Commands that fail (no reply, an
``ERR`` reply) raise the usual :class:`~station.errors.DriverError` subclasses.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import serial

from station.clock import Clock
from station.drivers.serial_base import SerialDriver
from station.errors import DriverError, InstrumentRefused, LinkTimeout

LINE_S = 0.72  # one data line every 0.0002 h
LINE_UNITS = 20  # 0.0002 h in the 1e-5 h units of the time field
WRAP = 10**7
FIELD_NAMES = ("time", "C1 of pickoff 1", "C1 of pickoff 2", "C1 of pickoff 3", "run number",
               "period sum")
# anything shaped like a data line (six 7-character fields), garbled or not
_DATA_SHAPE = re.compile(rb"^[^ \r\n]{7}( [^ \r\n]{7}){5}\r?\n$")
_MAX_SKIPPED = 10_000


@dataclass(frozen=True)
class DataLine:
    """One Appendix-A line that passed the checks."""

    time_hr: float  # processor clock, hours since TZERO
    c1: tuple[int, int, int]  # 100 MHz counts over the revolutions, pickoffs 1..3
    run: int
    period_sum: int
    raw: str

    def count_ratio(self, pickoff: int) -> float:
        """C1 / (C1 + C2) of ``pickoff`` (1..3) over the line's revolutions."""
        if pickoff not in (1, 2, 3):
            raise ValueError(f"pickoff must be 1, 2 or 3, got {pickoff!r}")
        c = self.c1[pickoff - 1]
        if c == 0:
            raise ValueError(
                f"pickoff {pickoff} has no count in this line (0000000): not selected, or its "
                "line of sight is off the pattern"
            )
        return c / self.period_sum


@dataclass(frozen=True)
class BadLine:
    """A data line that failed a check (or never came): ``raw`` as received, and why."""

    raw: str
    reason: str


def _decode(raw: bytes) -> str:
    return raw.rstrip(b"\r\n").decode("ascii", errors="backslashreplace")


def _show(b: bytes) -> str:
    return b.decode("ascii", errors="backslashreplace")


class ProcessorDriver(SerialDriver):
    def __init__(self, url: str, name: str = "processor", timeout: float = 5.0) -> None:
        super().__init__(name, url, timeout)
        # selection and run number as last set or read (the driver is the processor's only
        # host); None until known: lines() then asks SET? first
        self._known: tuple[tuple[int, int], int] | None = None
        self._stale = False  # a reply may still be on its way: resynchronise first

    # ----- exchanges: a stray data line or a late reply is never taken for a reply -----
    def query(self, cmd: str, timeout: float | None = None) -> str:
        """One command, one reply. Data lines still arriving from a stream are skipped, and
        after a timeout the link is first resynchronised (see :meth:`_sync`)."""
        if cmd.split(" ", 1)[0].upper() in ("SEL", "RUN"):
            self._known = None  # until the change is confirmed
        if self._stale:
            self._sync()
        waited = self.timeout if timeout is None else timeout
        raw = self._exchange(cmd, waited)
        if not raw.endswith(b"\n"):
            self._stale = True
            got = f" (partial reply {raw[:40]!r})" if raw else ""
            raise LinkTimeout(self.name, self.url, f"no reply to '{cmd}' within {waited:g} s{got}")
        try:
            text = raw.decode("ascii").strip()
        except UnicodeDecodeError:
            raise DriverError(
                self.name, self.url, f"garbled reply to '{cmd}': {raw[:40]!r}"
            ) from None
        if text.startswith("ERR"):
            parts = text.split(" ", 2)
            try:
                code = int(parts[1])
            except (IndexError, ValueError):
                raise DriverError(self.name, self.url, f"malformed error reply {text!r}") from None
            raise InstrumentRefused(self.name, self.url, code, parts[2] if len(parts) > 2 else "")
        return text

    def _exchange(self, cmd: str, timeout: float) -> bytes:
        """Write ``cmd``; the next line that is not a data line (partial on a timeout)."""
        port = self.port
        try:
            port.timeout = self.link_seconds(timeout)
            port.write((cmd + "\n").encode("ascii"))
            for _ in range(_MAX_SKIPPED):
                raw = port.read_until(b"\n")
                if not _DATA_SHAPE.match(raw):
                    return raw
            raise DriverError(self.name, self.url, f"no reply to '{cmd}' among data lines")
        except (serial.SerialException, OSError) as e:
            raise DriverError(self.name, self.url, f"link failed during '{cmd}': {e}") from None
        finally:
            port.timeout = self.link_seconds(self.timeout)

    def _sync(self) -> None:
        """After a timeout the late reply may still come: drop the input, ask ``*IDN?`` and
        skip everything before its answer (the one reply with commas that is no ERR)."""
        port = self.port
        try:
            port.reset_input_buffer()
            port.write(b"*IDN?\n")
            for _ in range(_MAX_SKIPPED):
                raw = port.read_until(b"\n")
                if not raw.endswith(b"\n"):
                    raise LinkTimeout(self.name, self.url, f"no reply to '*IDN?' within "
                                      f"{self.timeout:g} s (resynchronising after a timeout)")
                if b"," in raw and not raw.startswith(b"ERR"):
                    break
        except (serial.SerialException, OSError) as e:
            raise DriverError(self.name, self.url, f"link failed during '*IDN?': {e}") from None
        self._stale = False

    def clear(self) -> None:
        self._stale = True  # *CLS then waits for the link to be in step again
        super().clear()

    # ----- settings -----
    def select(self, a: int, b: int) -> None:
        """Counters A and B to pickoffs ``a`` and ``b`` (1..3, distinct)."""
        known = self._known
        self.command(f"SEL {int(a)} {int(b)}")
        if known is not None:
            self._known = ((int(a), int(b)), known[1])

    def revolutions(self, n: int) -> None:
        self.command(f"REV {int(n)}")

    def run_number(self, n: int) -> None:
        known = self._known
        self.command(f"RUN {int(n)}")
        if known is not None:
            self._known = (known[0], int(n))

    def threshold(self, volts: float) -> None:
        self.command(f"THR {float(volts):g}")

    def discriminator(self, us: float) -> None:
        self.command(f"DISC {float(us):g}")

    def delay(self, us: float) -> None:
        self.command(f"DELAY {float(us):g}")

    def time_zero(self) -> None:
        """Processor clock to 0 h."""
        self.command("TZERO")

    def halt(self) -> None:
        self.command("HALT")

    def settings(self) -> dict:
        """``{"pickoffs": (a, b), "revolutions", "run", "threshold_v", "min_width_us",
        "logic_delay_us"}`` as the processor reports them."""
        reply = self.query("SET?")
        try:
            a, b, rev, run, thr, disc, delay = reply.split()
            self._known = ((int(a), int(b)), int(run))
            return {
                "pickoffs": (int(a), int(b)),
                "revolutions": int(rev),
                "run": int(run),
                "threshold_v": float(thr),
                "min_width_us": float(disc),
                "logic_delay_us": float(delay),
            }
        except ValueError:
            raise DriverError(self.name, self.url, f"bad settings reply {reply!r}") from None

    # ----- data -----
    def lines(self, k: int) -> list[DataLine | BadLine]:
        """``GO k``, then the k data lines, each checked (a bad or lost one is a BadLine).

        A processor that does not acknowledge ``GO`` raises :class:`LinkTimeout`. If the
        stream stops early, the missing lines are ``BadLine("", "line lost: ...")`` and the
        driver halts the processor and empties its input, so the next command works.
        """
        if int(k) != k or k < 1:
            raise DriverError(self.name, self.url, f"lines(k) needs a whole k >= 1, got {k!r}")
        k = int(k)
        if self._known is None:
            self.settings()
        (a, b), run = self._known  # type: ignore[misc]
        selected = {a, b}
        try:
            self.command(f"GO {k}")
        except LinkTimeout:
            self._halt()
            raise
        out: list[DataLine | BadLine] = []
        checker = LineChecker(selected, run)
        port = self.port
        port.timeout = self.link_seconds(LINE_S * 1.5 + self.timeout)
        try:
            while len(out) < k:
                try:
                    raw = port.read_until(b"\n")
                except (serial.SerialException, OSError) as e:
                    raise DriverError(self.name, self.url, f"link failed during 'GO {k}': {e}") \
                        from None
                if not raw.endswith(b"\n"):
                    if raw:
                        out.append(BadLine(_decode(raw), "line cut off: no end of line"))
                    break
                out.append(checker.check(raw))
        finally:
            port.timeout = self.link_seconds(self.timeout)
        if len(out) < k:
            n = len(out)
            out.extend(BadLine("", f"line lost: stream ended after {n} of {k} lines")
                       for _ in range(k - n))
            self._halt()
        return out

    def _halt(self) -> None:
        """Stop the stream and drop what has arrived of it; the next command resynchronises
        the link first, so a HALT reply (or a line) still on its way is never misread."""
        try:
            self.port.write(b"HALT\n")
            self.port.reset_input_buffer()
        except (serial.SerialException, OSError):
            pass
        self._stale = True


class LineChecker:
    """Appendix-A checks of the lines of one stream, in order."""

    def __init__(self, selected: set[int], run: int) -> None:
        self.selected = selected
        self.run = run
        self.index = 0
        self.last_time: tuple[int, int] | None = None  # (index, time units) of the last good

    def check(self, raw: bytes) -> DataLine | BadLine:
        i = self.index
        self.index += 1
        text = _decode(raw)
        reason, time_units = self._reason(raw.rstrip(b"\r\n"), i)
        if reason is not None:
            return BadLine(text, reason)
        fields = [int(f) for f in text.split(" ")]
        if time_units is not None:
            self.last_time = (i, time_units)
        return DataLine(time_hr=fields[0] / 1e5, c1=(fields[1], fields[2], fields[3]),
                        run=fields[4], period_sum=fields[5], raw=text)

    def _reason(self, line: bytes, i: int) -> tuple[str | None, int | None]:
        fields = line.split(b" ")
        if len(fields) != 6:
            return f"expected 6 fields of 7 digits, got {len(fields)} fields", None
        for n, f in enumerate(fields, start=1):
            bad = next((j for j, c in enumerate(f) if c not in b"0123456789"), None)
            if bad is not None:
                return (f"field {n} has a non-digit ({FIELD_NAMES[n - 1]} "
                        f"'{_show(f)}', '{_show(f[bad:bad + 1])}' at position {bad + 1})"), None
            if len(f) != 7:
                return f"field {n} has {len(f)} digits, not 7 ({FIELD_NAMES[n - 1]})", None
        v = [int(f) for f in fields]
        t = v[0]
        if t % LINE_UNITS:
            return f"time {t:07d} not a multiple of 0.0002 h (20 units of 1e-5 h)", None
        if self.last_time is not None:
            j, tj = self.last_time
            want = (tj + LINE_UNITS * (i - j)) % WRAP
            if t != want:
                what = "the previous line" if j == i - 1 else f"line {j + 1} by {i - j} lines"
                return (f"time not 0.0002 h after {what} (got {t:07d}, expected {want:07d})",
                        None)
        if v[4] != self.run:
            return f"run number {v[4]:07d}, expected {self.run:07d} as set", t
        for p in (1, 2, 3):
            if p not in self.selected and v[p] != 0:
                return f"pickoff {p} is not selected but field {p + 1} is {v[p]:07d}", t
        period = v[5]
        if period == 0:
            return ("period sum is 0 (counter A saw no line-1 trailing edges: its pickoff is "
                    "off the pattern, or the rotor is not turning)"), t
        for p in sorted(self.selected):
            if v[p] >= period:
                return f"C1 >= period (pickoff {p}: {v[p]:07d} >= {period:07d})", t
        return None, t


# --------------------------------------------------------------------------- positioners


class _Positioner(SerialDriver):
    holding: tuple[str, ...] = ("HOLD",)

    def __init__(self, name: str, url: str, clock: Clock, timeout: float) -> None:
        super().__init__(name, url, timeout)
        self.clock = clock

    def status(self) -> str:
        return self.query("STAT?")

    def wait_hold(self, timeout: float = 120.0, poll: float = 0.5) -> None:
        """Poll ``STAT?`` on the station clock until the instrument holds still."""
        t_end = self.clock.now() + timeout
        while True:
            st = self.status()
            if st in self.holding:
                return
            if self.clock.now() >= t_end:
                raise LinkTimeout(self.name, self.url, f"still {st} after {timeout:g} s")
            self.clock.sleep(poll)


class HeadDriver(_Positioner):
    """Dividing head: absolute scale angle of the spindle, 1e-5 deg."""

    def __init__(self, url: str, clock: Clock, name: str = "head", timeout: float = 5.0):
        super().__init__(name, url, clock, timeout)

    def set(self, deg: float) -> None:
        """Spindle to the scale angle ``deg`` (taken modulo 360)."""
        self.command(f"SPIN {round(float(deg) % 360.0, 5) % 360.0:.5f}")

    def step(self, deg: float) -> None:
        """Spindle turned by ``deg`` (-360..360) from where it is."""
        self.command(f"STEP {float(deg):.5f}")

    def reading(self) -> float:
        return self.numbers("SPIN?", 1)[0]


class TurntableDriver(_Positioner):
    """Turntable azimuth and tilt, 1e-4 deg; the azimuth lock."""

    holding = ("HOLD", "LOCKED")

    def __init__(self, url: str, clock: Clock, name: str = "turntable", timeout: float = 5.0):
        super().__init__(name, url, clock, timeout)

    def azimuth(self, deg: float) -> None:
        """Azimuth to ``deg`` (taken modulo 360); refused while locked or moving."""
        self.command(f"AZ {round(float(deg) % 360.0, 4) % 360.0:.4f}")

    def tilt(self, deg: float) -> None:
        self.command(f"TILT {float(deg):.4f}")

    def readings(self) -> tuple[float, float]:
        """(azimuth, tilt) readings, deg."""
        return self.numbers("AZ?", 1)[0], self.numbers("TILT?", 1)[0]

    def lock(self) -> None:
        self.command("LOCK")

    def unlock(self) -> None:
        self.command("UNLOCK")


class TheodoliteDriver(SerialDriver):
    def __init__(self, url: str, name: str = "theodolite", timeout: float = 5.0):
        super().__init__(name, url, timeout)

    def read(self) -> tuple[float, float]:
        """Mirror-1 normal against the spindle, two axes, arcsec."""
        x, y = self.numbers("READ?", 2)
        return x, y


class ConsoleDriver(SerialDriver):
    def __init__(self, url: str, name: str = "console", timeout: float = 5.0):
        super().__init__(name, url, timeout)

    def spin_up(self) -> None:
        self.command("SPIN UP")

    def spin_off(self) -> None:
        self.command("SPIN OFF")

    def damping(self, on: bool) -> None:
        self.command("DAMP ON" if on else "DAMP OFF")

    def status(self) -> dict:
        """``{"suspended": bool, "spin_rps": float, "damping": bool, "pressure_torr": float}``."""
        reply = self.query("STAT?")
        f = reply.split()
        try:
            if f[0::2] != ["SUSP", "SPIN", "DAMP", "VAC"] or len(f) != 8:
                raise ValueError
            return {"suspended": f[1] == "1", "spin_rps": float(f[3]), "damping": f[5] == "1",
                    "pressure_torr": float(f[7])}
        except ValueError:
            raise DriverError(self.name, self.url, f"bad status reply {reply!r}") from None

    def speed(self) -> float:
        return self.numbers("SPEED?", 1)[0]
