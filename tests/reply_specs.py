"""Every driver reply parser, specified from the instruments' format strings, and a scripted
link that feeds a driver any bytes: shared by tests/test_driver_replies.py and
bench/fuzz_drivers.py.

The oracle here is written independently of station/drivers/replies.py: a token is
well-formed when printing its value with the instrument's format string gives the token
back (``f"{v:.7f}"``, ``str(n)``, ``f"{v:g}"``...), and a reply is the first complete line
that is either a refusal ``ERR <code> <text>`` or of the expected form. A well-formed
reply outside the instrument's range (or failing a check of the driver's state: the
autocollimator's field of view, a negative count in measure X-Y) is refused.
:func:`run_one` draws a reply, mutates it (lost, flipped, inserted bytes, lost decimal
point or sign, nan/inf/underscores, extra fields and lines, ...), predicts the outcome from
the oracle, calls the driver and classifies what came back as fuzz_core does.
"""

from __future__ import annotations

import math
import random
import re
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from station.drivers.cigtf import DvmDriver, FixtureDriver, GyroPowerDriver, SetupAidsDriver
from station.drivers.esg import (
    ConsoleDriver,
    HeadDriver,
    ProcessorDriver,
    TheodoliteDriver,
    TurntableDriver,
)
from station.drivers.isu.autocollimator import (
    FOV_DEG,
    READING_SLACK_DEG,
    ZENITH_RANGE_DEG,
    AutocollimatorDriver,
)
from station.drivers.isu.bubble_level import BubbleLevelDriver
from station.drivers.isu.counter import CounterDriver
from station.drivers.isu.oscillator import OscillatorDriver
from station.drivers.isu.patch_panel import PatchPanelDriver
from station.drivers.isu.table import TableDriver
from station.drivers.serial_base import SerialDriver
from station.errors import DriverError

REJECT = "<refused>"  # expected outcome: a DriverError
MAX_LINE = 514  # bytes of a line (with its \n) the drivers still read whole (MAX_REPLY + 2)

# --------------------------------------------------------------------------- scripted link


class ScriptedPort:
    """A pyserial-like port: every command line written gets the scripted bytes for that
    command (or the default answer: ``OK``, the identity) appended to the input at once.
    Reading never blocks: a read that finds no end of line returns what there is, as a
    timed-out read does."""

    def __init__(self, ident: str) -> None:
        self.ident = ident
        self.input = bytearray()
        self.written: list[str] = []
        self.script: dict[str, deque[bytes]] = {}
        self.timeout: float | None = 5.0
        self.is_open = True

    def answer(self, cmd: str, data: bytes) -> None:
        self.script.setdefault(cmd, deque()).append(data)

    @property
    def in_waiting(self) -> int:
        return len(self.input)

    def write(self, data: bytes) -> int:
        for line in bytes(data).split(b"\n")[:-1]:
            cmd = line.decode("ascii")
            self.written.append(cmd)
            q = self.script.get(cmd)
            if q:
                self.input += q.popleft()
            elif cmd == "*IDN?":
                self.input += self.ident.encode() + b"\n"
            else:
                self.input += b"OK\n"
        return len(data)

    def read(self, size: int = 1) -> bytes:
        out = bytes(self.input[:size])
        del self.input[:size]
        return out

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        i = self.input.find(expected)
        n = len(self.input) if i < 0 else i + len(expected)
        if size is not None:
            n = min(n, size)
        out = bytes(self.input[:n])
        del self.input[:n]
        return out

    def reset_input_buffer(self) -> None:
        self.input.clear()

    def close(self) -> None:
        self.is_open = False


def on_script(cls: Callable[..., SerialDriver], ident: str, **kw: Any) -> SerialDriver:
    """A driver of ``cls`` whose link is a ScriptedPort answering with identity ``ident``."""
    base = getattr(cls, "__name__", "Driver").removesuffix("Driver") or "driver"
    name = kw.pop("name", re.sub(r"(?<!^)(?=[A-Z])", "_", base).lower())  # GyroPower: gyro_power
    d = cls(name, "loop://", kw.pop("clock", None), **kw)
    d.port.close()
    d.port = ScriptedPort(ident)  # type: ignore[assignment]
    return d


# --------------------------------------------------------------------------- tokens


class Tok:
    """One token of a reply: how the instrument prints it, and what a token means."""

    literal = False

    def gen(self, rng: random.Random) -> str:
        raise NotImplementedError

    def read(self, t: str) -> tuple[bool, bool, Any]:
        """(well-formed, in range, value)."""
        raise NotImplementedError


def _float(t: str) -> float | None:
    try:
        v = float(t)
    except ValueError:
        return None
    return v if math.isfinite(v) else None


@dataclass
class Fixed(Tok):
    decimals: int
    lo: float
    hi: float

    def gen(self, rng: random.Random) -> str:
        span = self.hi - self.lo
        r = rng.random()
        if r < 0.15:
            v = rng.choice([self.lo, self.hi, 0.0, -0.0, self.lo - 10 ** -self.decimals,
                            self.hi + 10 ** -self.decimals, self.hi - 1e-9])
        elif r < 0.25:
            v = rng.uniform(self.lo - 0.2 * span, self.hi + 0.2 * span)
        else:
            v = rng.uniform(self.lo, self.hi)
        return f"{v:.{self.decimals}f}"

    def read(self, t: str) -> tuple[bool, bool, Any]:
        v = _float(t)
        if v is None or f"{v:.{self.decimals}f}" != t:
            return False, False, None
        return True, self.lo <= v <= self.hi, v


@dataclass
class Int(Tok):
    lo: int
    hi: int

    def gen(self, rng: random.Random) -> str:
        r = rng.random()
        if r < 0.15:
            v = rng.choice([self.lo, self.hi, self.lo - 1, self.hi + 1, 0])
        elif r < 0.5:
            v = rng.randint(max(self.lo, -1000), min(self.hi, 1000))
        else:
            v = rng.randint(self.lo, self.hi)
        return str(v)

    def read(self, t: str) -> tuple[bool, bool, Any]:
        try:
            v = int(t)
        except ValueError:
            return False, False, None
        if str(v) != t:
            return False, False, None
        return True, self.lo <= v <= self.hi, v


@dataclass
class G(Tok):
    lo: float
    hi: float

    def gen(self, rng: random.Random) -> str:
        r = rng.random()
        if r < 0.3:
            v = round(rng.uniform(self.lo, self.hi), rng.randint(0, 3))
        elif r < 0.4:
            v = rng.choice([self.lo, self.hi, self.lo / 2, self.hi * 2])
        else:
            v = rng.uniform(self.lo, self.hi)
        return f"{v:g}"

    def read(self, t: str) -> tuple[bool, bool, Any]:
        v = _float(t)
        if v is None or f"{v:g}" != t:
            return False, False, None
        return True, self.lo <= v <= self.hi, v


@dataclass
class E1(Tok):
    lo: float
    hi: float

    def gen(self, rng: random.Random) -> str:
        return f"{10 ** rng.uniform(-13, 4):.1E}"

    def read(self, t: str) -> tuple[bool, bool, Any]:
        v = _float(t)
        if v is None or f"{v:.1E}" != t:
            return False, False, None
        return True, self.lo <= v <= self.hi, v


@dataclass
class Word(Tok):
    choices: tuple[str, ...]

    def gen(self, rng: random.Random) -> str:
        return rng.choice(self.choices)

    def read(self, t: str) -> tuple[bool, bool, Any]:
        return t in self.choices, True, t


@dataclass
class Flag(Tok):
    def gen(self, rng: random.Random) -> str:
        return rng.choice("01")

    def read(self, t: str) -> tuple[bool, bool, Any]:
        return t in ("0", "1"), True, t == "1"


@dataclass
class Lit(Tok):
    text: str
    literal = True

    def gen(self, rng: random.Random) -> str:
        return self.text

    def read(self, t: str) -> tuple[bool, bool, Any]:
        return t == self.text, True, None


# --------------------------------------------------------------------------- replies


def _err(text: str) -> bool:
    """``ERR <code>[ <text>]``: a refusal (code as str(int) prints it, up to 4 digits)."""
    if not text.startswith("ERR "):
        return False
    code, _, _rest = text[4:].partition(" ")
    try:
        n = int(code)
    except ValueError:
        return False
    return str(n) == code and abs(n) <= 9999


@dataclass
class Reply:
    """What one command's reply may be: alternatives of token lists, a check of the values
    against the driver's state, and refusals that are a value (NO RETURN)."""

    command: str
    alts: list[list[Tok]]
    sep: str = " "
    check: Callable[[tuple], bool] = lambda v: True
    err_values: dict[str, Any] = field(default_factory=dict)
    items: tuple[int, int] | None = None  # a list reply: one token repeated lo..hi times

    def generate(self, rng: random.Random) -> str:
        if self.items is not None:
            tok = self.alts[0][0]
            assert isinstance(tok, Word)
            n = rng.randint(*self.items)
            return self.sep.join(sorted(rng.sample(tok.choices, n)))
        if self.err_values and rng.random() < 0.1:
            return rng.choice(list(self.err_values))
        return self.sep.join(t.gen(rng) for t in rng.choice(self.alts))

    def read(self, text: str) -> tuple[str, Any] | None:
        """("value", v) or ("refused", None) for the reply line ``text``; None if ``text``
        is not of this reply's form (the driver drops it and reads on)."""
        if text in self.err_values:
            return "value", self.err_values[text]
        if _err(text):
            return "refused", None
        parts = text.split(self.sep)
        if self.items is not None:
            tok = self.alts[0][0]
            lo, hi = self.items
            if not (lo <= len(parts) <= hi and len(set(parts)) == len(parts)
                    and all(tok.read(p)[0] for p in parts)):
                return None
            return "value", parts
        for i, toks in enumerate(self.alts):
            if len(parts) != len(toks):
                continue
            got = [t.read(p) for t, p in zip(toks, parts, strict=True)]
            if not all(g[0] for g in got):
                continue
            vals = tuple(g[2] for g, t in zip(got, toks, strict=True) if not t.literal)
            if not all(g[1] for g in got) or not self.check(vals):
                return "refused", None
            return "value", (i, vals) if len(self.alts) > 1 else vals
        return None


def data_shaped(body: bytes) -> bool:
    """Six fields of seven bytes, none a space or CR: the ESG processor's data lines."""
    parts = body.split(b" ")
    return len(parts) == 6 and all(len(p) == 7 and b"\r" not in p for p in parts)


def expect(reply: Reply, response: bytes, background: Callable[[bytes], bool] | None
           ) -> tuple[str, Any]:
    """What the driver must make of ``response`` to the command of ``reply``."""
    for raw in response.split(b"\n")[:-1]:
        if len(raw) + 1 > MAX_LINE:
            continue  # over-long: dropped
        body = raw[:-1] if raw.endswith(b"\r") else raw
        if background is not None and background(body):
            continue
        try:
            text = body.decode("ascii")
        except UnicodeDecodeError:
            continue
        if not text.isprintable():
            continue
        out = reply.read(text)
        if out is not None:
            return out
    return "refused", None  # no reply of the form within the timeout


# --------------------------------------------------------------------------- mutations

_JUNK = ["nan", "inf", "-inf", "NaN", "Infinity", "1e3", "1_0", "0x1A", "+1.5", "1.5.0",
         ".5", "5.", "--1", "\u0661", "1,5", "", "OK", "ERR", "ERR 1x bad", "ERR 12 bad",
         "NONE", "HOLD", "ERR 30 NO RETURN", "ISU-LAB,TT-4AX,0,1.0", "1", "0", "-0"]


def _digits(text: str) -> list[int]:
    return [i for i, c in enumerate(text) if c.isdigit()]


def _tokens(text: str) -> list[tuple[int, int]]:
    return [m.span() for m in re.finditer(r"[^ ,]+", text)]


def mutate_text(rng: random.Random, text: str) -> str:
    """One change to the text of a reply (still one line, unless a byte becomes \\n)."""
    k = rng.randrange(16)
    digits = _digits(text)
    toks = _tokens(text)
    if k == 0 and text:  # lost byte
        i = rng.randrange(len(text))
        return text[:i] + text[i + 1:]
    if k == 1:  # inserted byte
        i = rng.randrange(len(text) + 1)
        return text[:i] + chr(rng.randrange(32, 127)) + text[i:]
    if k == 2 and "." in text:  # lost decimal point
        dots = [i for i, c in enumerate(text) if c == "."]
        i = rng.choice(dots)
        return text[:i] + text[i + 1:]
    if k == 3 and "-" in text:  # lost sign
        i = text.index("-")
        return text[:i] + text[i + 1:]
    if k == 4 and toks:  # a sign added
        a, _ = rng.choice(toks)
        return text[:a] + rng.choice("-+") + text[a:]
    if k == 5 and toks:  # a token replaced by something float()/int() would take
        a, b = rng.choice(toks)
        return text[:a] + rng.choice(_JUNK) + text[b:]
    if k == 6 and len(digits) >= 2:  # underscore between digits
        i = rng.choice(digits[1:])
        return text[:i] + "_" + text[i:]
    if k == 7 and digits:  # a digit changed (well-formed, another value)
        i = rng.choice(digits)
        return text[:i] + rng.choice("0123456789") + text[i + 1:]
    if k == 8:  # an extra field
        extra = rng.choice(["0", "1.5", "12.30", "OK", "x"])
        return text + " " + extra if rng.random() < 0.5 else extra + " " + text
    if k == 9 and len(toks) > 1:  # a field lost
        a, b = rng.choice(toks)
        return (text[:a] + text[b:]).strip(" ,").replace("  ", " ").replace(",,", ",")
    if k == 10:  # spacing
        return rng.choice([" " + text, text + " ", text.replace(" ", "  ", 1),
                           text.replace(" ", "\t", 1), text.replace(",", " ", 1)])
    if k == 11 and digits:  # leading zero, or a digit doubled
        a, _ = rng.choice(toks)
        return text[:a] + "0" + text[a:] if rng.random() < 0.5 else \
            text[:digits[0]] + text[digits[0]] + text[digits[0]:]
    if k == 12:
        return text.lower() if rng.random() < 0.5 else text.upper()
    if k == 13 and text:  # truncated
        return text[:rng.randrange(len(text))]
    if k == 14 and toks:  # fields swapped or a token duplicated
        a, b = rng.choice(toks)
        return text[:b] + text[a:b] + text[b:]
    return text


def mutate(rng: random.Random, text: str, reply: Reply) -> tuple[bytes, bytes]:
    """(input waiting before the command, the reply's bytes) for one mutated reply."""
    line = text
    pending = b""
    r = rng.random()
    if r < 0.06:
        return pending, (line + "\n").encode()  # untouched
    for _ in range(1 + (rng.random() < 0.25) + (rng.random() < 0.1)):
        line = mutate_text(rng, line)
    data = line.encode("ascii", errors="backslashreplace")
    if r < 0.25:  # byte-level damage: a bit flipped, a byte lost, a byte inserted
        data = (text + "\n").encode()
        for _ in range(1 + (rng.random() < 0.3)):
            kind = rng.randrange(4)
            i = rng.randrange(len(data))
            if kind == 0:
                data = data[:i] + bytes([data[i] ^ (1 << rng.randrange(8))]) + data[i + 1:]
            elif kind == 1:
                data = data[:i] + data[i + 1:]
            elif kind == 2:
                data = data[:i] + bytes([rng.randrange(256)]) + data[i:]
            else:
                data = data[:i] + data[i:i + 1] + data[i:]
        return pending, data
    ending = rng.choice([b"\n"] * 8 + [b"\r\n", b"\r\r\n", b"", b"\n\n"])
    body = data + ending
    r2 = rng.random()
    if r2 < 0.08:  # a stray line waiting before the command
        pending = rng.choice([b"junk\n", (text + "\n").encode(), b"OK\n", b"12.30 3.40\n",
                              b"partial"])
        body = (text + "\n").encode()
    elif r2 < 0.14:  # an extra line after the reply
        body += rng.choice([b"junk\n", (text + "\n").encode(), b"OK\n", b"\xff\n"])
    elif r2 < 0.20:  # a line that is not the reply before it
        body = rng.choice([b"junk\n", b"\xfe\xff\n", b"ERR\n", b"x" * 700 + b"\n"]) + body
    elif r2 < 0.23:  # over-long
        body = b"9" * rng.choice([600, 2000]) + b"\n" + body
    return pending, body


# --------------------------------------------------------------------------- specifications


@dataclass
class Plan:
    """One use of a parser: the call, the replies it reads in order, its result from their
    values."""

    call: Callable[[Any], Any]
    replies: list[Reply]
    result: Callable[[list[Any]], Any]


@dataclass
class Spec:
    name: str  # Driver.method
    make: Callable[[], Any]
    plan: Callable[[random.Random, Any], Plan]
    background: Callable[[bytes], bool] | None = None


def _one(call: Callable[[Any], Any], reply: Reply,
         result: Callable[[Any], Any] = lambda v: v[0]) -> Plan:
    return Plan(call, [reply], lambda vs: result(vs[0]))


ISU = "ISU-LAB"
IDENT = {
    TableDriver: f"{ISU},TT-4AX,0,1.0", CounterDriver: f"{ISU},FC-1,C3,1.0",
    OscillatorDriver: f"{ISU},MO-5M,0,1.0", PatchPanelDriver: f"{ISU},PATCH-PANEL,0,1.0",
    AutocollimatorDriver: f"{ISU},AC-2,1,1.0", BubbleLevelDriver: f"{ISU},BL-2,0,1.0",
    FixtureDriver: "CIGTF,GOERZ-2AX-PROGRAMMER,0,1.0", DvmDriver: "CIGTF,DVM-AVERAGER,0,1.0",
    GyroPowerDriver: "CIGTF,GYRO-POWER,0,1.0", SetupAidsDriver: "CIGTF,SETUP-AIDS,0,1.0",
    ProcessorDriver: "ESG-LAB,DATA-PROCESSOR,0,1.0",
    HeadDriver: "ESG-LAB,DIVIDING-HEAD,0,1.0", TurntableDriver: "ESG-LAB,TURNTABLE-TILT,0,1.0",
    TheodoliteDriver: "ESG-LAB,THEODOLITE,0,1.0", ConsoleDriver: "ESG-LAB,GYRO-CONSOLE,0,1.0",
    SerialDriver: "SOME MAKER,SOME MODEL,SN 1,2.05",
}
PATCH_LINES = ("G1", "G1+", "G1-", "G2", "G2+", "G2-", "G3", "G3+", "G3-", "A1S1", "A1S2",
               "A2S1", "A2S2", "A3S1", "A3S2", "TROT", "OSC1", "OSC2")


def _maker(cls: Any, **kw: Any) -> Callable[[], Any]:
    def make() -> Any:
        return on_script(cls, IDENT[cls], **kw)
    return make


@dataclass
class Free(Tok):
    """Printable ASCII without a comma (an identity field); ``alnum``: letters and digits."""

    choices: tuple[str, ...]
    empty: bool = False
    alnum: bool = False

    def gen(self, rng: random.Random) -> str:
        return rng.choice(self.choices)

    def read(self, t: str) -> tuple[bool, bool, Any]:
        ok = (bool(t) or self.empty) and "," not in t and t.isascii() and t.isprintable()
        if self.alnum:
            ok = ok and t.isalnum()
        return ok, True, t


@dataclass
class Version(Tok):
    def gen(self, rng: random.Random) -> str:
        return rng.choice(("1.0", "2.05", "10"))

    def read(self, t: str) -> tuple[bool, bool, Any]:
        parts = t.split(".")
        return all(p and p.isascii() and p.isdigit() for p in parts), True, t


def _identity_tok(cls: Any) -> Reply:
    maker, model = IDENT[cls].split(",")[:2]
    return Reply("*IDN?", [[Word((maker,)), Word((model,)),
                            Free(("0", "1", "C3", "SN1"), alnum=True), Version()]], sep=",")


def _direction(az: float, zen: float) -> tuple[float, float, float]:
    a, z = math.radians(az), math.radians(zen)
    return math.cos(z), math.cos(a) * math.sin(z), math.sin(a) * math.sin(z)


def _angle(u: tuple[float, float, float], v: tuple[float, float, float]) -> float:
    cx = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
    return math.degrees(math.atan2(math.sqrt(sum(c * c for c in cx)),
                                   sum(a * b for a, b in zip(u, v, strict=True))))


def _measure_plan(rng: random.Random, d: AutocollimatorDriver) -> Plan:
    """MEAS? near the pointing (aimed first, or with the pointing unknown)."""
    zlo, zhi = ZENITH_RANGE_DEG
    aimed = rng.random() < 0.7
    az0, zen0 = rng.uniform(0, 360), rng.uniform(zlo, zhi)
    if aimed:
        d.aim(az0, zen0)
        pointing = (float(f"{az0:.6f}") % 360.0, float(f"{zen0:.6f}"))
    limit = FOV_DEG + READING_SLACK_DEG

    def check(v: tuple) -> bool:
        if aimed:
            return _angle(_direction(*v), _direction(*pointing)) <= limit
        return True

    class Near(Tok):
        def gen(self, rng: random.Random) -> str:
            r = rng.uniform(0, 1.4 * limit)
            th = rng.uniform(0, 2 * math.pi)
            zen = zen0 + r * math.cos(th)
            az = (az0 + r * math.sin(th) / math.sin(math.radians(zen))) % 360.0
            return f"{az:.7f} {zen:.7f}"

    near = Near()
    reply = Reply("MEAS?", [[Fixed(7, 0.0, 360.0),
                             Fixed(7, zlo - limit, zhi + limit)]],
                  check=check, err_values={"ERR 30 NO RETURN": None})
    base_gen = reply.generate

    def generate(rng: random.Random) -> str:
        return near.gen(rng) if rng.random() < 0.8 else base_gen(rng)

    reply.generate = generate  # type: ignore[method-assign]
    return Plan(lambda d: d.measure(), [reply], lambda vs: vs[0])


def _counter_read_plan(rng: random.Random, d: CounterDriver) -> Plan:
    mode = rng.choice([None, "measure Z", "measure X-Y"])
    if mode:
        d.set_mode(mode)
    reg = 10**12 - 1
    return _one(lambda d: d.read(timeout=5.0),
                Reply("READ?", [[Int(-reg, reg)]],
                      check=lambda v: not (mode == "measure X-Y" and v[0] < 0)))


def _s_t_plan(rng: random.Random, d: OscillatorDriver) -> Plan:
    k = rng.choice([1, 2])
    return Plan(lambda d: d.s_t(k),
                [Reply(f"DIV? {k}", [[Int(1, 10**9)]]),
                 Reply("FREQ?", [[Fixed(1, 1.0, 1e9)]])],
                lambda vs: vs[0][0] / vs[1][0])


def _settings_result(v: tuple) -> dict:
    a, b, rev, run, thr, disc, delay = v
    return {"pickoffs": (a, b), "revolutions": rev, "run": run, "threshold_v": thr,
            "min_width_us": disc, "logic_delay_us": delay}


SPECS: list[Spec] = [
    Spec("SerialDriver.identify", _maker(SerialDriver),
         lambda rng, d: _one(lambda d: d.identify(), Reply("*IDN?", [[
             Free(("SOME MAKER", "ACME")), Free(("SOME MODEL", "X-1")),
             Free(("SN 1", "", "7"), empty=True), Version()]], sep=","), lambda v: ",".join(v))),
    Spec("SerialDriver.command", _maker(SerialDriver),
         lambda rng, d: _one(lambda d: d.command("FROB 1"), Reply("FROB 1", [[Lit("OK")]]),
                             lambda v: None)),
    Spec("TableDriver.identify", _maker(TableDriver),
         lambda rng, d: _one(lambda d: d.identify(), _identity_tok(TableDriver),
                             lambda v: ",".join(v))),
    Spec("TableDriver.position(1)", _maker(TableDriver),
         lambda rng, d: _one(lambda d: d.position(1),
                             Reply("POS? 1", [[Fixed(7, -5.01, 95.01)]]))),
    Spec("TableDriver.position(2-4)", _maker(TableDriver),
         lambda rng, d: (lambda a: _one(lambda d: d.position(a),
                                        Reply(f"POS? {a}", [[Fixed(7, 0.0, 360.0)]])))(
             rng.choice([2, 3, 4]))),
    Spec("TableDriver.rate", _maker(TableDriver),
         lambda rng, d: _one(lambda d: d.rate(2), Reply("RATE? 2", [[Fixed(7, -20.0, 20.0)]]))),
    Spec("TableDriver.status", _maker(TableDriver),
         lambda rng, d: _one(lambda d: d.status(), Reply("STAT?", [[Word(
             ("HOLD", "MOVING", "SETTLING", "ACCEL", "ROTATING"))] * 4], sep=","), list)),
    Spec("TableDriver.interlock", _maker(TableDriver),
         lambda rng, d: _one(lambda d: d.interlock(),
                             Reply("ILCK?", [[Word(("CLOSED", "OPEN"))]]))),
    Spec("CounterDriver.read", _maker(CounterDriver), _counter_read_plan),
    Spec("CounterDriver.queued", _maker(CounterDriver),
         lambda rng, d: _one(lambda d: d.queued(), Reply("COUN?", [[Int(0, 256)]]))),
    Spec("CounterDriver.state", _maker(CounterDriver),
         lambda rng, d: _one(lambda d: d.state(), Reply("STATE?", [[Word(("OPER", "STBY"))]]))),
    Spec("CounterDriver.self_test", _maker(CounterDriver),
         lambda rng, d: _one(lambda d: d.self_test(), Reply("TEST?", [[Lit("PASS")]]),
                             lambda v: "PASS")),
    Spec("OscillatorDriver.nominal_hz", _maker(OscillatorDriver),
         lambda rng, d: _one(lambda d: d.nominal_hz(),
                             Reply("FREQ?", [[Fixed(1, 1.0, 1e9)]]))),
    Spec("OscillatorDriver.divider", _maker(OscillatorDriver),
         lambda rng, d: _one(lambda d: d.divider(2), Reply("DIV? 2", [[Int(1, 10**9)]]))),
    Spec("OscillatorDriver.s_t", _maker(OscillatorDriver), _s_t_plan),
    Spec("OscillatorDriver.self_test", _maker(OscillatorDriver),
         lambda rng, d: _one(lambda d: d.self_test(), Reply("TEST?", [[Lit("PASS")]]),
                             lambda v: "PASS")),
    Spec("OscillatorDriver.status", _maker(OscillatorDriver),
         lambda rng, d: _one(lambda d: d.status(), Reply("STAT?", [[Word(("LOCKED",))]]))),
    Spec("PatchPanelDriver.connection", _maker(PatchPanelDriver),
         lambda rng, d: _one(lambda d: d.connection(2, "X"),
                             Reply("CONN? C2 X", [[Word((*PATCH_LINES, "NONE"))]]),
                             lambda v: None if v[0] == "NONE" else v[0])),
    Spec("PatchPanelDriver.lines", _maker(PatchPanelDriver),
         lambda rng, d: _one(lambda d: d.lines(),
                             Reply("LINES?", [[Word(PATCH_LINES)]], sep=",",
                                   items=(1, len(PATCH_LINES))), lambda v: v)),
    Spec("AutocollimatorDriver.pointing", _maker(AutocollimatorDriver),
         lambda rng, d: _one(lambda d: d.pointing(),
                             Reply("AIM?", [[Fixed(6, 0.0, 360.0), Fixed(6, 60.0, 120.0)]]),
                             lambda v: v)),
    Spec("AutocollimatorDriver.measure", _maker(AutocollimatorDriver), _measure_plan),
    Spec("BubbleLevelDriver.corrections", _maker(BubbleLevelDriver),
         lambda rng, d: _one(lambda d: d.corrections(),
                             Reply("LEV?", [[Fixed(2, -121.0, 121.0)] * 2]), lambda v: v)),
    Spec("FixtureDriver.position", _maker(FixtureDriver),
         lambda rng, d: _one(lambda d: d.position(),
                             Reply("POS?", [[Int(0, 359), Int(0, 359)]]), lambda v: v)),
    Spec("FixtureDriver.status", _maker(FixtureDriver),
         lambda rng, d: _one(lambda d: d.status(),
                             Reply("STAT?", [[Word(("HOLD", "MOVING", "FAULT"))]]))),
    Spec("DvmDriver.aperture", _maker(DvmDriver),
         lambda rng, d: _one(lambda d: d.aperture(), Reply("APER?", [[G(0.001, 3600.0)]]))),
    Spec("DvmDriver.average", _maker(DvmDriver),
         lambda rng, d: _one(lambda d: d.average(), Reply("AVG?", [[Fixed(7, -100.0, 100.0)]]))),
    Spec("GyroPowerDriver.status", _maker(GyroPowerDriver),
         lambda rng, d: _one(lambda d: d.status(),
                             Reply("PWR?", [[Lit("OFF")], [Lit("ON"), Fixed(1, 0.0, 1e9)]]),
                             lambda v: (False, 0.0) if v[0] == 0 else (True, v[1][0]))),
    Spec("GyroPowerDriver.rotor_voltage", _maker(GyroPowerDriver),
         lambda rng, d: _one(lambda d: d.rotor_voltage(),
                             Reply("VOLT?", [[Fixed(2, 10.0, 40.0)]]))),
    Spec("SetupAidsDriver.levels", _maker(SetupAidsDriver),
         lambda rng, d: _one(lambda d: d.levels(),
                             Reply("LEVEL?", [[Fixed(1, -3600.0, 3600.0)] * 2]), lambda v: v)),
    Spec("SetupAidsDriver.azimuth", _maker(SetupAidsDriver),
         lambda rng, d: _one(lambda d: d.azimuth(),
                             Reply("AZIM?", [[Fixed(1, -3600.0, 3600.0)]]))),
    Spec("ProcessorDriver.settings", _maker(ProcessorDriver),
         lambda rng, d: _one(lambda d: d.settings(), Reply("SET?", [[
             Int(1, 3), Int(1, 3), Int(1, 10), Int(0, 9_999_999), G(0.1, 5.0), G(2.0, 24.0),
             G(20.0, 2000.0)]], check=lambda v: v[0] != v[1] and v[2] in (1, 2, 4, 8, 10)),
             _settings_result), background=data_shaped),
    Spec("HeadDriver.reading", _maker(HeadDriver),
         lambda rng, d: _one(lambda d: d.reading(), Reply("SPIN?", [[Fixed(5, 0.0, 360.0)]]))),
    Spec("HeadDriver.status", _maker(HeadDriver),
         lambda rng, d: _one(lambda d: d.status(), Reply("STAT?", [[Word(("HOLD", "MOVING"))]]))),
    Spec("TurntableDriver.readings", _maker(TurntableDriver),
         lambda rng, d: Plan(lambda d: d.readings(),
                             [Reply("AZ?", [[Fixed(4, 0.0, 360.0)]]),
                              Reply("TILT?", [[Fixed(4, -90.0, 90.0)]])],
                             lambda vs: (vs[0][0], vs[1][0]))),
    Spec("TurntableDriver.status", _maker(TurntableDriver),
         lambda rng, d: _one(lambda d: d.status(),
                             Reply("STAT?", [[Word(("HOLD", "MOVING", "LOCKED"))]]))),
    Spec("TheodoliteDriver.read", _maker(TheodoliteDriver),
         lambda rng, d: _one(lambda d: d.read(),
                             Reply("READ?", [[Fixed(2, -1800.0, 1800.0)] * 2]), lambda v: v)),
    Spec("ConsoleDriver.status", _maker(ConsoleDriver),
         lambda rng, d: _one(lambda d: d.status(), Reply("STAT?", [[
             Lit("SUSP"), Flag(), Lit("SPIN"), Fixed(2, 0.0, 500.0), Lit("DAMP"), Flag(),
             Lit("VAC"), E1(1e-12, 760.0)]]),
             lambda v: {"suspended": v[0], "spin_rps": v[1], "damping": v[2],
                        "pressure_torr": v[3]})),
    Spec("ConsoleDriver.speed", _maker(ConsoleDriver),
         lambda rng, d: _one(lambda d: d.speed(), Reply("SPEED?", [[Fixed(2, 0.0, 500.0)]]))),
    Spec("ConsoleDriver.lamp_reading", _maker(ConsoleDriver),
         lambda rng, d: _one(lambda d: d.lamp_reading(2),
                             Reply("LAMP? 2", [[Fixed(1, 50.0, 150.0)]]))),
    Spec("ProcessorDriver.scope", _maker(ProcessorDriver),
         lambda rng, d: _one(lambda d: d.scope(3), Reply("SCOPE? 3", [
             [Lit("OFF")], [Fixed(2, 0.0, 20.0)] + [Fixed(1, 0.0, 10000.0)] * 4]),
             lambda v: None if v[0] == 0 else {"height_v": v[1][0],
                                               "widths_us": list(v[1][1:4]),
                                               "logic_to_line_us": v[1][4]}),
         background=data_shaped),
]


# --------------------------------------------------------------------------- one input


def _outcome(spec: Spec, plan: Plan, responses: list[bytes]) -> tuple[str, Any]:
    vals = []
    for reply, data in zip(plan.replies, responses, strict=True):
        kind, v = expect(reply, data, spec.background)
        if kind == "refused":
            return REJECT, None
        vals.append(v)
    return "value", plan.result(vals)


def _call(drv: Any, plan: Plan) -> tuple[str, Any]:
    try:
        return "value", plan.call(drv)
    except DriverError:
        return REJECT, None


def run_one(spec: Spec, rng: random.Random) -> str:
    """One mutated reply to one parser: "accepted", "rejected" or "wrong" (fuzz_core).

    A second call with clean replies follows: a line left over from the first (an extra
    line, a late reply) must be dropped, never taken as the second call's reply."""
    drv = spec.make()
    port: ScriptedPort = drv.port
    plan = spec.plan(rng, drv)
    texts = [r.generate(rng) for r in plan.replies]
    m = rng.randrange(len(texts))
    pending, data = mutate(rng, texts[m], plan.replies[m])
    responses = [(t + "\n").encode() for t in texts]
    responses[m] = data
    port.input += pending
    for reply, resp in zip(plan.replies, responses, strict=True):
        port.answer(reply.command, resp)
    want = _outcome(spec, plan, responses)
    got = _call(drv, plan)
    if got != want:
        return "wrong"
    # the same call again, clean: leftovers must not shift it
    port.script.clear()
    texts2 = [r.generate(rng) for r in plan.replies]
    clean = [(t + "\n").encode() for t in texts2]
    for reply, text, resp in zip(plan.replies, texts2, clean, strict=True):
        if reply.command == "*IDN?":
            port.ident = text  # a resynchronising *IDN? gets it too
        else:
            port.answer(reply.command, resp)
    if _call(drv, plan) != _outcome(spec, plan, clean):
        return "wrong"
    return "rejected" if want[0] == REJECT else "accepted"


# --------------------------------------------------------------------------- ESG data lines

WRAP = 10**7


def format_line(n: int, c1: tuple[int, int, int], run: int, period: int) -> str:
    """Appendix A: time (20 n units of 1e-5 h), C1 of pickoffs 1-3, run, period sum, each
    as seven digits modulo 10^7."""
    return " ".join(f"{v % WRAP:07d}" for v in (20 * n, *c1, run, period))


def gen_line(rng: random.Random, n: int, selected: set[int], run: int) -> str:
    period = rng.randint(1, WRAP - 1) if rng.random() < 0.95 else 0
    c1 = tuple((rng.randint(0, max(period - 1, 0)) if rng.random() < 0.97 else
                rng.randint(0, WRAP - 1)) if p in selected else
               (0 if rng.random() < 0.97 else rng.randint(1, 99)) for p in (1, 2, 3))
    return format_line(n, c1, run if rng.random() < 0.97 else run + 1, period)  # type: ignore


def line_fields(raw: bytes) -> list[int] | None:
    """The six fields of an Appendix-A line: seven ASCII digits each, one space apart."""
    body = raw[:-1] if raw.endswith(b"\n") else raw
    body = body[:-1] if body.endswith(b"\r") else body
    parts = body.split(b" ")
    if len(parts) != 6 or any(len(p) != 7 or any(c < 48 or c > 57 for c in p) for p in parts):
        return None
    return [int(p) for p in parts]


class LineOracle:
    """The Appendix-A checks, written from docs/protocols.md: what each line of a stream
    must give (a DataLine's values, or None for a BadLine)."""

    def __init__(self, selected: set[int], run: int) -> None:
        self.selected, self.run = selected, run
        self.i = 0
        self.last: tuple[int, int] | None = None  # (index, time) of the last good line

    def see(self, raw: bytes) -> tuple | None:
        i = self.i
        self.i += 1
        v = line_fields(raw)
        if v is None or v[0] % 20:
            return None
        if self.last is not None and v[0] != (self.last[1] + 20 * (i - self.last[0])) % WRAP:
            return None
        if v[4] != self.run or v[5] == 0:
            return None
        if any(v[p] != 0 for p in (1, 2, 3) if p not in self.selected):
            return None
        if any(v[p] >= v[5] for p in self.selected):
            return None
        self.last = (i, v[0])
        return (v[0] / 1e5, (v[1], v[2], v[3]), v[4], v[5])


def _mutate_line(rng: random.Random, line: str) -> bytes:
    r = rng.random()
    if r < 0.1:
        return (line + "\n").encode()
    if r < 0.4:
        data = bytearray((line + "\n").encode())
        i = rng.randrange(len(data))
        kind = rng.randrange(3)
        if kind == 0:
            data[i] ^= 1 << rng.randrange(8)
        elif kind == 1:
            del data[i]
        else:
            data.insert(i, rng.randrange(256))
        return bytes(data)
    return (mutate_text(rng, line) + rng.choice(["\n", "\n", "\r\n", "\r\r\n"])).encode(
        "ascii", errors="backslashreplace")


def _same(got: Any, want: tuple | None) -> bool:
    from station.drivers.esg import BadLine, DataLine
    if want is None:
        return isinstance(got, BadLine) and bool(got.reason)
    return isinstance(got, DataLine) and (got.time_hr, got.c1, got.run, got.period_sum) == want


def run_line_checker(rng: random.Random) -> str:
    """Three lines of one stream, one mutated, through LineChecker.check."""
    from station.drivers.esg import LineChecker
    selected = set(rng.sample([1, 2, 3], 2))
    run = rng.randint(0, WRAP - 1)
    n0 = rng.randint(0, 600_000)
    lines = [(gen_line(rng, n0 + i, selected, run) + "\n").encode() for i in range(3)]
    m = rng.randrange(3)
    lines[m] = _mutate_line(rng, lines[m].decode().rstrip("\n"))
    checker, oracle = LineChecker(selected, run), LineOracle(selected, run)
    ok = True
    for raw in lines:
        ok &= _same(checker.check(raw), oracle.see(raw))
    mutated = any(line_fields(x) is None for x in lines)
    return "wrong" if not ok else ("rejected" if mutated else "accepted")


def run_lines(rng: random.Random) -> str:
    """ProcessorDriver.lines(k) over a scripted stream with one line mutated (or lost, cut,
    doubled, or an extra line), then a clean SET? that leftovers must not disturb."""
    drv: ProcessorDriver = on_script(ProcessorDriver, IDENT[ProcessorDriver])  # type: ignore
    port: ScriptedPort = drv.port  # type: ignore[assignment]
    a, b = rng.sample([1, 2, 3], 2)
    run = rng.randint(0, 9_999_999)
    port.answer("SET?", f"{a} {b} 10 {run} 1.5 20 241\n".encode())
    k = rng.randint(1, 5)
    n0 = rng.randint(0, 600_000)
    lines = [(gen_line(rng, n0 + i, {a, b}, run) + "\n").encode() for i in range(k + 1)]
    m = rng.randrange(k)
    r = rng.random()
    if r < 0.1:
        lines[m] = lines[m][:-1]  # end of line lost: two lines run together
    elif r < 0.15:
        lines[m] = b"9" * 600 + b"\n"
    else:
        lines[m] = _mutate_line(rng, lines[m].decode().rstrip("\n"))
    extra = rng.random() < 0.3
    stream = b"".join(lines if extra else lines[:k])
    if rng.random() < 0.1:
        stream = stream[:rng.randrange(len(stream))]  # the stream stops early
    port.answer(f"GO {k}", b"OK\n" + stream)
    # what lines(k) must give: each complete line checked, a cut one named, the rest lost
    oracle = LineOracle({a, b}, run)
    want: list[tuple | None] = []
    rest = stream
    while len(want) < k:
        i = rest.find(b"\n")
        if i < 0 or i + 1 > MAX_LINE:
            if rest:
                want.append(None)
            break
        want.append(oracle.see(rest[:i + 1]))
        rest = rest[i + 1:]
    want += [None] * (k - len(want))
    try:
        got = drv.lines(k)
    except DriverError:
        return "wrong"  # GO was acknowledged: lines() reports bad lines, it does not raise
    if len(got) != k or not all(_same(g, w) for g, w in zip(got, want, strict=True)):
        return "wrong"
    port.answer("SET?", f"{b} {a} 4 {run} 2.5 10 300\n".encode())
    try:
        if drv.settings() != {"pickoffs": (b, a), "revolutions": 4, "run": run,
                              "threshold_v": 2.5, "min_width_us": 10.0,
                              "logic_delay_us": 300.0}:
            return "wrong"
    except DriverError:
        return "wrong"
    return "accepted" if all(w is not None for w in want) else "rejected"
