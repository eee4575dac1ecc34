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
from typing import Any

import serial

from station.clock import Clock
from station.drivers.driver_set import DriverSet
from station.drivers.replies import (
    Form,
    OneOf,
    fixed,
    flag,
    general,
    integer,
    literal,
    scientific,
    word,
)
from station.drivers.serial_base import MAX_REPLY, SerialDriver, show, strip_eol
from station.errors import DriverError, LinkTimeout

LINE_S = 0.72  # one data line every 0.0002 h
LINE_UNITS = 20  # 0.0002 h in the 1e-5 h units of the time field
WRAP = 10**7
REVOLUTIONS = (1, 2, 4, 8, 10)
MAX_LINES = 1_000_000  # GO k accepts k up to this
_SETTINGS_TAIL = [
    integer("revolutions", 1, 10), integer("run number", 0, WRAP - 1),
    general("threshold, V", 0.1, 5.0), general("discriminator, us", 2.0, 24.0),
    general("logic delay, us", 20.0, 2000.0)]
# two pickoffs selected, or three on a three-counter processor
SETTINGS = OneOf(Form([integer("pickoff a", 1, 3), integer("pickoff b", 1, 3),
                       *_SETTINGS_TAIL]),
                 Form([integer("pickoff a", 1, 3), integer("pickoff b", 1, 3),
                       integer("pickoff c", 1, 3), *_SETTINGS_TAIL]))
SCOPE = OneOf(Form([literal("OFF")]),
              Form([fixed("pulse height, V", 2, 0.0, 20.0),
                    fixed("logic line width, us", 1, 0.0, 10000.0),
                    fixed("line 1 width, us", 1, 0.0, 10000.0),
                    fixed("line 2 width, us", 1, 0.0, 10000.0),
                    fixed("logic to line 1, us", 1, 0.0, 10000.0)]))
LAMP = Form([fixed("lamp current, percent", 1, 50.0, 150.0)])
FIELD_NAMES = ("time", "C1 of pickoff 1", "C1 of pickoff 2", "C1 of pickoff 3", "run number",
               "period sum")
# anything shaped like a data line (six 7-character fields), garbled or not
_DATA_SHAPE = re.compile(rb"[^ \r\n]{7}(?: [^ \r\n]{7}){5}")


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
    return show(strip_eol(raw))


class ProcessorDriver(SerialDriver):
    model = ("ESG-LAB", "DATA-PROCESSOR")

    def __init__(self, name: str, url: str, clock: Clock | None = None,
                 timeout: float = 5.0) -> None:
        super().__init__(name, url, clock, timeout)
        # selection and run number as last set or read (the driver is the processor's only
        # host); None until known: lines() then asks SET? first
        self._known: tuple[tuple[int, ...], int] | None = None

    # ----- exchanges: a data line still arriving from a stream is never taken for a reply
    def _background(self, body: bytes) -> bool:
        return _DATA_SHAPE.fullmatch(body) is not None

    def _exchange(self, cmd: str, form: Any, timeout: float | None) -> str:
        if cmd.split(" ", 1)[0].upper() in ("SEL", "RUN"):
            self._known = None  # until the change is confirmed
        return super()._exchange(cmd, form, timeout)

    # ----- settings -----
    def select(self, *pickoffs: int) -> None:
        """Counters A and B (and C, on a three-counter processor) to the pickoffs (1..3,
        distinct)."""
        known = self._known
        sel = tuple(int(p) for p in pickoffs)
        self.command("SEL " + " ".join(map(str, sel)))
        if known is not None:
            self._known = (sel, known[1])

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
        """``{"pickoffs": (a, b) or (a, b, c), "revolutions", "run", "threshold_v",
        "min_width_us", "logic_delay_us"}`` as the processor reports them."""
        form, v = self.ask("SET?", SETTINGS)
        sel = tuple(v[:2 + form])
        rev, run, thr, disc, delay = v[2 + form:]
        if len(set(sel)) < len(sel):
            raise self.refuse("SET?", f"pickoffs must be distinct, got "
                              f"{' '.join(map(str, sel))}")
        if rev not in REVOLUTIONS:
            raise self.refuse("SET?", f"revolutions {rev} not one of {REVOLUTIONS}")
        self._known = (sel, run)
        if not form:  # the two-counter reading as it always was
            return {"pickoffs": (sel[0], sel[1]), "revolutions": rev, "run": run,
                    "threshold_v": thr, "min_width_us": disc, "logic_delay_us": delay}
        return {"pickoffs": sel, "revolutions": rev, "run": run, "threshold_v": thr,
                "min_width_us": disc, "logic_delay_us": delay}

    def scope(self, pickoff: int) -> dict | None:
        """Pickoff ``pickoff``'s pulses on the processor's scope: ``{"height_v",
        "widths_us": [logic, line 1, line 2], "logic_to_line_us"}``; None off the pattern."""
        i, v = self.ask(f"SCOPE? {int(pickoff)}", SCOPE)
        if i == 0:
            return None
        return {"height_v": v[0], "widths_us": [v[1], v[2], v[3]], "logic_to_line_us": v[4]}

    # ----- data -----
    def lines(self, k: int) -> list[DataLine | BadLine]:
        """``GO k``, then the k data lines, each checked (a bad or lost one is a BadLine).

        A processor that does not acknowledge ``GO`` raises :class:`LinkTimeout`. If the
        stream stops early, the missing lines are ``BadLine("", "line lost: ...")`` and the
        driver halts the processor and empties its input, so the next command works.
        """
        try:
            k = self.whole(k, "k", 1, MAX_LINES)
        except DriverError:
            raise DriverError(self.name, self.url, f"lines(k) needs a whole k >= 1 (at most "
                              f"{MAX_LINES}), got {k!r}") from None
        known = self._known
        if known is None:
            s = self.settings()
            known = (s["pickoffs"], s["run"])
        sel, run = known
        selected = set(sel)
        try:
            self.command(f"GO {k}")
        except LinkTimeout:
            self._halt()
            raise
        out: list[DataLine | BadLine] = []
        checker = LineChecker(selected, run)
        port = self.port
        try:
            while len(out) < k:
                try:
                    port.timeout = self.link_seconds(LINE_S * 1.5 + self.timeout)
                    raw = port.read_until(b"\n", MAX_REPLY + 2)
                except (serial.SerialException, OSError) as e:
                    raise DriverError(self.name, self.url, f"link failed during 'GO {k}': {e}") \
                        from None
                if not raw.endswith(b"\n"):
                    if len(raw) >= MAX_REPLY + 2:
                        out.append(BadLine(_decode(raw[:80]) + "...", "line too long: no end "
                                           f"of line within {MAX_REPLY} bytes"))
                    elif raw:
                        out.append(BadLine(_decode(raw), "line cut off: no end of line"))
                    break
                out.append(checker.check(raw))
        finally:
            self._set_timeout(self.timeout)
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
            self.lose_step()
        except (serial.SerialException, OSError):
            self.out_of_step = True


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
        reason, time_units = self._reason(strip_eol(raw), i)
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
                        f"'{show(f)}', '{show(f[bad:bad + 1])}' at position {bad + 1})"), None
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


# ranges (docs/protocols.md, ESG laboratory): scales wrap to [0, 360) (rounding may print
# 360); the tilt stops at +/-90 deg; the theodolite's field is +/-30 arcmin (a choice: the
# mirror normal stays within arcseconds of the spindle); the rotor runs at 200-500 rps
# (esg.spin_rps); the pressure reads up to one atmosphere.
TILT_LIMIT_DEG = 90.0
THEODOLITE_FIELD_ARCSEC = 1800.0
MAX_SPIN_RPS = 500.0
HEAD_READING = Form([fixed("spindle reading, deg", 5, 0.0, 360.0)])
AZIMUTH = Form([fixed("azimuth reading, deg", 4, 0.0, 360.0)])
TILT = Form([fixed("tilt reading, deg", 4, -TILT_LIMIT_DEG, TILT_LIMIT_DEG)])
MIRROR = Form([fixed("x, arcsec", 2, -THEODOLITE_FIELD_ARCSEC, THEODOLITE_FIELD_ARCSEC),
               fixed("y, arcsec", 2, -THEODOLITE_FIELD_ARCSEC, THEODOLITE_FIELD_ARCSEC)])
SPEED = Form([fixed("spin speed, rps", 2, 0.0, MAX_SPIN_RPS)])
CONSOLE = Form([literal("SUSP"), flag("suspended"), literal("SPIN"),
                fixed("spin speed, rps", 2, 0.0, MAX_SPIN_RPS), literal("DAMP"),
                flag("damping"), literal("VAC"), scientific("pressure, torr", 1e-12, 760.0)])


class _Positioner(SerialDriver):
    holding: tuple[str, ...] = ("HOLD",)
    status_form = Form([word("state", "HOLD", "MOVING")])

    def status(self) -> str:
        return self.ask("STAT?", self.status_form)[0]

    def wait_hold(self, timeout: float = 120.0, poll: float = 0.5) -> None:
        """Poll ``STAT?`` on the station clock until the instrument holds still."""
        clock = self.needs_clock()
        t_end = clock.now() + timeout
        while True:
            st = self.status()
            if st in self.holding:
                return
            if clock.now() >= t_end:
                raise LinkTimeout(self.name, self.url, f"still {st} after {timeout:g} s")
            clock.sleep(poll)


class HeadDriver(_Positioner):
    """Dividing head: absolute scale angle of the spindle, 1e-5 deg."""

    model = ("ESG-LAB", "DIVIDING-HEAD")

    def set(self, deg: float) -> None:
        """Spindle to the scale angle ``deg`` (taken modulo 360)."""
        self.command(f"SPIN {round(float(deg) % 360.0, 5) % 360.0:.5f}")

    def step(self, deg: float) -> None:
        """Spindle turned by ``deg`` (-360..360) from where it is."""
        self.command(f"STEP {float(deg):.5f}")

    def reading(self) -> float:
        return self.ask("SPIN?", HEAD_READING)[0]

    def shim(self, x_arcsec: float, y_arcsec: float) -> None:
        """Re-shim the case: the mirror along the spindle moved by (x, y) arcsec on the
        theodolite's axes (refused while the spindle moves or the rotor spins)."""
        self.command(f"SHIM {float(x_arcsec):.2f} {float(y_arcsec):.2f}")

    def mount(self, mirror: int) -> None:
        """The case set back on the plate with mirror ``mirror`` (1, 2) along the spindle
        (refused while the spindle moves or the rotor spins)."""
        self.command(f"MOUNT {int(mirror)}")


class TurntableDriver(_Positioner):
    """Turntable azimuth and tilt, 1e-4 deg; the azimuth lock."""

    model = ("ESG-LAB", "TURNTABLE-TILT")
    holding = ("HOLD", "LOCKED")
    status_form = Form([word("state", "HOLD", "MOVING", "LOCKED")])

    def azimuth(self, deg: float) -> None:
        """Azimuth to ``deg`` (taken modulo 360); refused while locked or moving."""
        self.command(f"AZ {round(float(deg) % 360.0, 4) % 360.0:.4f}")

    def tilt(self, deg: float) -> None:
        self.command(f"TILT {float(deg):.4f}")

    def readings(self) -> tuple[float, float]:
        """(azimuth, tilt) readings, deg."""
        return self.ask("AZ?", AZIMUTH)[0], self.ask("TILT?", TILT)[0]

    def lock(self) -> None:
        self.command("LOCK")

    def unlock(self) -> None:
        self.command("UNLOCK")


class TheodoliteDriver(SerialDriver):
    model = ("ESG-LAB", "THEODOLITE")

    def read(self) -> tuple[float, float]:
        """Mirror-1 normal against the spindle, two axes, arcsec."""
        x, y = self.ask("READ?", MIRROR)
        return x, y


class ConsoleDriver(SerialDriver):
    model = ("ESG-LAB", "GYRO-CONSOLE")

    def spin_up(self) -> None:
        self.command("SPIN UP")

    def spin_off(self) -> None:
        self.command("SPIN OFF")

    def damping(self, on: bool) -> None:
        self.command("DAMP ON" if on else "DAMP OFF")

    def translate(self, pickoff: int, a_arcsec: float, b_arcsec: float) -> None:
        """Pickoff ``pickoff``'s line of sight moved (a, b) arcsec along the next two case
        axes in its fixture (pickoff 1: c2, c3)."""
        self.command(f"XLATE {int(pickoff)} {float(a_arcsec):.2f} {float(b_arcsec):.2f}")

    def status(self) -> dict:
        """``{"suspended": bool, "spin_rps": float, "damping": bool, "pressure_torr": float}``."""
        susp, rps, damp, torr = self.ask("STAT?", CONSOLE)
        return {"suspended": susp, "spin_rps": rps, "damping": damp, "pressure_torr": torr}

    def speed(self) -> float:
        return self.ask("SPEED?", SPEED)[0]

    def lamp(self, pickoff: int, percent: float) -> None:
        """Lamp current of a pickoff, percent of nominal (50..150)."""
        self.command(f"LAMP {int(pickoff)} {float(percent):.1f}")

    def lamp_reading(self, pickoff: int) -> float:
        return self.ask(f"LAMP? {int(pickoff)}", LAMP)[0]


@dataclass
class EsgDrivers(DriverSet):
    """What an ESG procedure sees: processor, head, turntable, theodolite, console, clock."""

    processor: ProcessorDriver
    head: HeadDriver
    turntable: TurntableDriver
    theodolite: TheodoliteDriver
    console: ConsoleDriver
