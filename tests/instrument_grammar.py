"""The serial instruments' command grammars as docs/protocols.md states them: an oracle
written from the documentation, independent of instruments/, for the property tests
(tests/test_instrument_commands.py) and the fuzzer (bench/fuzz_instruments.py).

A :class:`Grammar` says whether a command line is valid (word, argument count, argument
syntax and documented ranges), what a valid command answers (a regular expression) and
which refusals of a valid command depend only on the instrument's state (busy, interlock,
wiring...). It draws valid lines and mutated lines from a ``random.Random``; a mutated
line is classified by the oracle, never assumed invalid.
"""

from __future__ import annotations

import math
import random
import re
from collections.abc import Callable
from dataclasses import dataclass, field

MAX_LINE = 256
_INT = re.compile(r"-?[0-9]+")
_REAL = re.compile(r"-?([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][-+]?[0-9]+)?")
_ERR = re.compile(r"ERR ([0-9]+) \S.*")
NUM = r"-?[0-9]+\.[0-9]"


# ----------------------------------------------------------------------------- arguments


@dataclass(frozen=True)
class Int:
    lo: int
    hi: int

    def valid(self, tok: str) -> bool:
        return bool(_INT.fullmatch(tok)) and self.lo <= int(tok) <= self.hi

    def draw(self, rng: random.Random) -> str:
        v = rng.choice((self.lo, self.hi, rng.randint(self.lo, self.hi)))
        if v >= 0 and rng.random() < 0.1:
            return f"{v:0{rng.randint(1, 12)}d}"  # leading zeros are still the number
        return str(v)


@dataclass(frozen=True)
class Real:
    lo: float
    hi: float
    hi_open: bool = False

    def value(self, tok: str) -> float | None:
        if not _REAL.fullmatch(tok):
            return None
        v = float(tok)
        return v if math.isfinite(v) else None

    def valid(self, tok: str) -> bool:
        v = self.value(tok)
        if v is None or v < self.lo or v > self.hi:
            return False
        return not (self.hi_open and v >= self.hi)

    def draw(self, rng: random.Random) -> str:
        r = rng.random()
        if r < 0.05:
            v = self.lo
        elif r < 0.1 and not self.hi_open:
            v = self.hi
        else:
            v = rng.uniform(self.lo, self.hi)
        fmt = rng.choice(("{:.7f}", "{:.3f}", "{:g}", "{:.4e}", "{:.1f}", "{:.0f}", "{}"))
        tok = fmt.format(v)
        if rng.random() < 0.05 and "." in tok and "e" not in tok:
            tok = tok.rstrip("0")  # "12." is a number too
        return tok


@dataclass(frozen=True)
class Word:
    options: tuple[str, ...]

    def valid(self, tok: str) -> bool:
        return tok.upper() in self.options

    def draw(self, rng: random.Random) -> str:
        w = rng.choice(self.options)
        return w.lower() if rng.random() < 0.2 else w


Arg = Int | Real | Word


@dataclass(frozen=True)
class Cmd:
    """One command word: its arguments (the last ``optional`` may be left out), the reply to a
    valid line (a regular expression, matched whole) and any rule across arguments."""

    word: str
    args: tuple[Arg, ...] = ()
    reply: str = "OK"
    optional: int = 0
    check: Callable[[list[str]], bool] | None = None
    deferred: bool = False  # the reply may come later (a reading, an integration)

    def valid_args(self, args: list[str]) -> bool:
        if not len(self.args) - self.optional <= len(args) <= len(self.args):
            return False
        if not all(a.valid(t) for a, t in zip(self.args, args, strict=False)):
            return False
        return self.check is None or self.check(args)


@dataclass
class Grammar:
    name: str
    ident: str
    commands: list[Cmd]
    state_codes: frozenset[int] = frozenset()  # refusals of a valid line that depend on state
    words: dict[str, Cmd] = field(init=False)

    def __post_init__(self) -> None:
        common = [Cmd("*IDN?", reply=re.escape(self.ident)),
                  Cmd("SYST:ERR?", reply=r"0 no error|[0-9]+ \S.*"), Cmd("*CLS"), Cmd("DCL")]
        self.words = {c.word: c for c in common + self.commands}

    # --- the oracle ---
    def classify(self, raw: bytes) -> str:
        """``"blank"`` (no reply), ``"valid"`` or ``"invalid"`` for one line (no newline)."""
        if len(raw) > MAX_LINE:  # counted with any CR before the newline
            return "invalid"
        raw = raw.rstrip(b"\r")
        if not raw.strip(b" "):
            return "blank"
        if any(not 0x20 <= b <= 0x7E for b in raw):
            return "invalid"
        words = raw.decode("ascii").split(" ")
        words = [w for w in words if w]
        cmd = self.words.get(words[0].upper())
        return "valid" if cmd is not None and cmd.valid_args(words[1:]) else "invalid"

    def command(self, raw: bytes) -> Cmd:
        return self.words[raw.rstrip(b"\r").decode("ascii").split()[0].upper()]

    def judge(self, raw: bytes, reply: str | None, deferred: bool) -> str:
        """The fuzz outcome of ``raw`` answered by ``reply`` (None: no reply; ``deferred``:
        a reply that will come later): "accepted", "rejected" or "wrong"."""
        kind = self.classify(raw)
        if kind == "blank":
            return "accepted" if reply is None and not deferred else "wrong"
        if reply is None and not deferred:
            return "wrong"  # every non-blank line gets one reply
        err = _ERR.fullmatch(reply) if reply is not None else None
        if reply is not None and reply.startswith("ERR") and err is None:
            return "wrong"  # a refusal without a code
        if kind == "invalid":
            return "rejected" if err is not None and int(err.group(1)) != 200 else "wrong"
        cmd = self.command(raw)
        if err is not None:
            return "accepted" if int(err.group(1)) in self.state_codes else "wrong"
        if deferred:
            return "accepted" if cmd.deferred else "wrong"
        assert reply is not None
        return "accepted" if re.fullmatch(cmd.reply, reply) else "wrong"

    # --- drawing lines ---
    def draw_valid(self, rng: random.Random, full: bool = False,
                   with_args: bool = False) -> list[str]:
        """The words of a valid line (all optional arguments with ``full``; a command that
        takes arguments with ``with_args``, if the instrument has one)."""
        cmds = list(self.words.values())
        if with_args and any(c.args for c in cmds):
            cmds = [c for c in cmds if c.args]
        for _ in range(100):
            cmd = rng.choice(cmds)
            n = len(cmd.args) if full else len(cmd.args) - rng.randint(0, cmd.optional)
            words = [cmd.word.lower() if rng.random() < 0.1 else cmd.word]
            words += [a.draw(rng) for a in cmd.args[:n]]
            if cmd.valid_args(words[1:]):
                return words
        # draws that keep missing a cross-argument rule (a shrinking property test's zeros):
        # a command without one
        cmd = next(c for c in cmds + list(self.words.values()) if c.check is None)
        return [cmd.word] + [a.draw(rng) for a in cmd.args]

    def draw_line(self, rng: random.Random) -> bytes:
        """A valid line (a third of the draws) or a mutated one."""
        if rng.random() < 1 / 3:
            words = self.draw_valid(rng)
            return join(words, rng)
        words = self.draw_valid(rng, full=rng.random() < 0.7, with_args=rng.random() < 0.7)
        for _ in range(rng.choice((1, 1, 1, 2, 3))):
            for _try in range(5):  # a mutation that changes nothing (no argument) is redrawn
                new = rng.choice(TOKEN_MUTATIONS)(words, rng)
                if new != words:
                    break
            else:
                new = _extra(words, rng)
            words = new
        raw = join(words, rng)
        if rng.random() < 0.25:
            raw = rng.choice(BYTE_MUTATIONS)(raw, rng)
        return raw


def join(words: list[str], rng: random.Random) -> bytes:
    sep = " " if rng.random() < 0.9 else " " * rng.randint(2, 3)
    line = sep.join(words)
    if rng.random() < 0.05:
        line = " " + line + " "
    return line.encode("utf-8")


# ----------------------------------------------------------------------------- mutations

_LETTERS = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
_UNICODE_DIGITS = "\u0663\uff13\u00b2\u0967\u2155\U0001d7d9"  # Arabic-Indic 3, fullwidth 3, ...
_JUNK = ["nan", "inf", "-inf", "Infinity", "1_000", "+5", "0x1f", "1e5", "--1", "1.2.3", "",
         "TRUE", "NONE", "\u00b0", "10%", "5,0", "1/2", "'", "\"1\"", "1e999", "-", "."]


def _pick(words: list[str], rng: random.Random, args_only: bool = True) -> int | None:
    lo = 1 if args_only else 0
    return rng.randrange(lo, len(words)) if len(words) > lo else None


def _extra(words, rng):
    return words + [rng.choice([str(rng.randint(-9, 99)), "X", "1.5", rng.choice(_JUNK) or "0"])]


def _drop(words, rng):
    i = _pick(words, rng)
    return words if i is None else words[:i] + words[i + 1:]


def _duplicate(words, rng):
    i = _pick(words, rng, args_only=False)
    return words if i is None else words[:i + 1] + words[i:]


def _swap(words, rng):
    if len(words) < 3:
        return words
    i, j = rng.sample(range(1, len(words)), 2)
    w = list(words)
    w[i], w[j] = w[j], w[i]
    return w


def _in_token(edit: Callable[[str, random.Random], str]):
    def mutate(words, rng):
        i = _pick(words, rng)
        if i is None:
            return words
        w = list(words)
        w[i] = edit(w[i], rng)
        return w
    return mutate


def _underscore(tok, rng):
    k = rng.randint(1, max(1, len(tok) - 1))
    return tok[:k] + "_" + tok[k:]


def _unicode_digit(tok, rng):
    digits = [k for k, c in enumerate(tok) if c.isdigit()]
    if not digits:
        return tok + rng.choice(_UNICODE_DIGITS)
    k = rng.choice(digits)
    return tok[:k] + rng.choice(_UNICODE_DIGITS) + tok[k + 1:]


def _inner_space(tok, rng):
    if len(tok) < 2:
        return tok + " " + tok
    k = rng.randint(1, len(tok) - 1)
    return tok[:k] + " " + tok[k:]


def _head(words, rng):
    w = list(words)
    h = w[0]
    r = rng.random()
    if r < 0.4:
        w[0] = h + rng.choice(_LETTERS)
    elif r < 0.7 and len(h) > 1:
        k = rng.randrange(len(h))
        w[0] = h[:k] + h[k + 1:]
    else:
        k = rng.randrange(len(h))
        w[0] = h[:k] + rng.choice(_LETTERS + "?*:") + h[k + 1:]
    return w


def _out_of_range(words, rng):
    i = _pick(words, rng)
    if i is None:
        return words
    w = list(words)
    w[i] = rng.choice(["-1", "0", "4", "5", "361", "-361", "3601", "100000000001", "1e12",
                       "-9999999999", "99999999999999999999999999999", "0.5"])
    return w


TOKEN_MUTATIONS: list[Callable[[list[str], random.Random], list[str]]] = [
    _extra, _extra, _drop, _duplicate, _swap, _head, _out_of_range,
    _in_token(_underscore),
    _in_token(lambda t, rng: "+" + t),
    _in_token(lambda t, rng: t + rng.choice(_LETTERS)),
    _in_token(lambda t, rng: t + rng.choice([".0", "e1", "E+2", ".", "e"])),
    _in_token(_unicode_digit),
    _in_token(_inner_space),
    _in_token(lambda t, rng: rng.choice(_JUNK)),
    _in_token(lambda t, rng: t.lower()),
]


def _insert_byte(raw: bytes, rng: random.Random) -> bytes:
    k = rng.randint(0, len(raw))
    b = rng.choice([0, 9, 11, 12, 13, 27, 32, 127, 0x80, 0xFF, rng.randint(0, 255)])
    b = 32 if b == 10 else b  # a newline would make two lines
    return raw[:k] + bytes([b]) + raw[k:]


def _delete_byte(raw: bytes, rng: random.Random) -> bytes:
    if not raw:
        return raw
    k = rng.randrange(len(raw))
    return raw[:k] + raw[k + 1:]


def _replace_byte(raw: bytes, rng: random.Random) -> bytes:
    if not raw:
        return raw
    k = rng.randrange(len(raw))
    b = rng.randint(0, 255)
    b = 32 if b == 10 else b
    return raw[:k] + bytes([b]) + raw[k + 1:]


def _long(raw: bytes, rng: random.Random) -> bytes:
    return raw + b" " + b"9" * rng.randint(MAX_LINE - len(raw), MAX_LINE + 40)


BYTE_MUTATIONS: list[Callable[[bytes, random.Random], bytes]] = [
    _insert_byte, _delete_byte, _replace_byte, _long,
    lambda raw, rng: raw + b"\r",  # a CR before the newline is dropped: still the same line
]


# ----------------------------------------------------------------------------- ISU lab

AXIS = Int(1, 4)
STATUS = "HOLD|MOVING|SETTLING|ACCEL|ROTATING"
LINES = ("A1S1", "A1S2", "A2S1", "A2S2", "A3S1", "A3S2", "G1", "G1+", "G1-", "G2", "G2+", "G2-",
         "G3", "G3+", "G3-", "OSC1", "OSC2", "TROT")
COUNTERS = tuple(f"C{i}" for i in range(1, 7))
INPUTS = ("X", "Y", "Z")
TRUNNION = (-5.0, 95.0)  # table.trunnion_range_deg
MAX_RATE, MAX_ACCEL = 20.0, 10.0  # table.max_rate_deg_s, table.max_accel_deg_s2


def _f(tok: str) -> float:
    return float(tok)


def _pos_rule(a: list[str]) -> bool:
    return int(a[0]) != 1 or TRUNNION[0] <= _f(a[1]) <= TRUNNION[1]


def _rate_rule(a: list[str]) -> bool:
    return int(a[0]) != 1 and abs(_f(a[1])) <= MAX_RATE


def _ramp_rule(a: list[str]) -> bool:
    return int(a[0]) != 1 and 0 < abs(_f(a[1])) <= MAX_ACCEL and abs(_f(a[2])) <= MAX_RATE


TABLE = Grammar("table", "ISU-LAB,TT-4AX,0,1.0", [
    Cmd("POS", (AXIS, Real(-3600, 3600)), check=_pos_rule),
    Cmd("RATE", (AXIS, Real(-MAX_RATE, MAX_RATE)), check=_rate_rule),
    Cmd("RAMP", (AXIS, Real(-MAX_ACCEL, MAX_ACCEL), Real(-MAX_RATE, MAX_RATE)),
        check=_ramp_rule),
    Cmd("STOP", (AXIS,), optional=1),
    Cmd("HOME"),
    Cmd("POS?", (AXIS,), reply=NUM + r"{7}"),
    Cmd("RATE?", (AXIS,), reply=NUM + r"{7}"),
    Cmd("STAT?", (AXIS,), optional=1, reply=rf"({STATUS})(,({STATUS})){{3}}|{STATUS}"),
    Cmd("ILCK?", reply="CLOSED|OPEN"),
    Cmd("PPR", (Int(1, 3600),)),
    Cmd("PPR?", reply=r"[0-9]+"),
], state_codes=frozenset({15}))

PATCH_PANEL = Grammar("patch_panel", "ISU-LAB,PATCH-PANEL,0,1.0", [
    Cmd("CONN", (Word(LINES), Word(COUNTERS), Word(INPUTS))),
    Cmd("DISC", (Word(COUNTERS), Word(INPUTS))),
    Cmd("CONN?", (Word(COUNTERS), Word(INPUTS)),
        reply="NONE|" + "|".join(re.escape(x) for x in LINES)),
    Cmd("CLR"),
    Cmd("LINES?", reply=re.escape(",".join(sorted(LINES)))),
])

COUNTER = Grammar("counter", "ISU-LAB,FC-1,C1,1.0", [
    Cmd("*RST"),
    Cmd("MODE", (Word(("Z", "XY", "X-Y")),)),
    Cmd("MODE?", reply="Z|XY"),
    Cmd("PRESET", (Int(1, 10**11),)),
    Cmd("PRESET?", reply=r"[0-9]+"),
    Cmd("OPER"),
    Cmd("STBY"),
    Cmd("STATE?", reply="OPER|STBY"),
    Cmd("READ?", reply=r"-?[0-9]+", deferred=True),
    Cmd("FETC?", reply=r"-?[0-9]+|NONE"),
    Cmd("COUN?", reply=r"[0-9]+"),
    Cmd("CLR"),
    Cmd("TEST?", reply="PASS"),
], state_codes=frozenset({21, 22, 23, 25, 26}))

AUTOCOLLIMATOR = Grammar("autocollimator", "ISU-LAB,AC-2,1,1.0", [
    Cmd("AIM", (Real(-3600, 3600), Real(60.0, 120.0))),
    Cmd("AIM?", reply=r"[0-9]+\.[0-9]{6} [0-9]+\.[0-9]{6}"),
    Cmd("MEAS?", reply=r"[0-9]+\.[0-9]{7} [0-9]+\.[0-9]{7}", deferred=True),
    Cmd("TEST?", reply="PASS"),
])

BUBBLE_LEVELS = Grammar("bubble_levels", "ISU-LAB,BL-2,0,1.0", [
    Cmd("LEV?", reply=NUM + "{2} " + NUM + "{2}"),
], state_codes=frozenset({40}))

OSCILLATOR = Grammar("oscillator", "ISU-LAB,MO-5M,0,1.0", [
    Cmd("FREQ?", reply=r"[0-9]+\.[0-9]"),
    Cmd("DIV?", (Int(1, 2),), reply=r"[0-9]+"),
    Cmd("STAT?", reply="LOCKED"),
    Cmd("TEST?", reply="PASS"),
])

# ----------------------------------------------------------------------------- CIGTF lab

VH = Word(("V", "H"))
FIXTURE = Grammar("fixture", "CIGTF,GOERZ-2AX-PROGRAMMER,0,1.0", [
    Cmd("MOVE", (VH, Int(0, 359))),
    Cmd("TURN", (VH, Int(-360, 360))),
    Cmd("POS?", reply=r"[0-9]+ [0-9]+"),
    Cmd("STAT?", reply="HOLD|MOVING|FAULT"),
], state_codes=frozenset({16, 17}))

DVM = Grammar("dvm", "CIGTF,DVM-AVERAGER,0,1.0", [
    Cmd("AVG?", reply=NUM + "{7}", deferred=True),
    Cmd("APER?", reply=r"[0-9.e+-]+"),
])

GYRO_POWER = Grammar("gyro_power", "CIGTF,GYRO-POWER,0,1.0", [
    Cmd("PWR", (Word(("ON", "OFF")),)),
    Cmd("PWR?", reply=r"OFF|ON [0-9]+\.[0-9]"),
    Cmd("VOLT", (Real(10.0, 40.0),)),
    Cmd("VOLT?", reply=r"[0-9]+\.[0-9]{2}"),
], state_codes=frozenset({18}))

SETUP_AIDS = Grammar("setup_aids", "CIGTF,SETUP-AIDS,0,1.0", [
    Cmd("LEVEL?", reply=NUM + " " + NUM),
    Cmd("AZIM?", reply=NUM),
    Cmd("TILT", (Word(("EW", "NS")), Real(-600.0, 600.0))),
    Cmd("BASE", (Real(-3600.0, 3600.0),)),
], state_codes=frozenset({13, 16}))

# ----------------------------------------------------------------------------- ESG lab

REVOLUTIONS = (1, 2, 4, 8, 10)
PROCESSOR = Grammar("processor", "ESG-LAB,DATA-PROCESSOR,0,1.0", [
    Cmd("SEL", (Int(1, 3), Int(1, 3)), check=lambda a: int(a[0]) != int(a[1])),
    Cmd("REV", (Int(1, 10),), check=lambda a: int(a[0]) in REVOLUTIONS),
    Cmd("RUN", (Int(0, 9_999_999),)),
    Cmd("THR", (Real(0.1, 5.0),)),
    Cmd("DISC", (Real(2.0, 24.0),)),
    Cmd("DELAY", (Real(20.0, 2000.0),)),
    Cmd("TZERO"),
    Cmd("GO", (Int(1, 1_000_000),), optional=1),
    Cmd("HALT"),
    Cmd("SET?", reply=r"[1-3] [1-3] (1|2|4|8|10) [0-9]+ \S+ \S+ \S+"),
    Cmd("SCOPE?", (Int(1, 3),),
        reply=r"OFF|[0-9]+\.[0-9]{2} [0-9]+\.[0-9] [0-9]+\.[0-9] [0-9]+\.[0-9] [0-9]+\.[0-9]"),
], state_codes=frozenset({16}))

HEAD = Grammar("head", "ESG-LAB,DIVIDING-HEAD,0,1.0", [
    Cmd("SPIN", (Real(0.0, 360.0, hi_open=True),)),
    Cmd("STEP", (Real(-360.0, 360.0),)),
    Cmd("SPIN?", reply=r"[0-9]+\.[0-9]{5}"),
    Cmd("STAT?", reply="HOLD|MOVING"),
    Cmd("SHIM", (Real(-120.0, 120.0), Real(-120.0, 120.0))),
    Cmd("MOUNT", (Int(1, 2),)),
    Cmd("MOUNT?", reply="[12]"),
], state_codes=frozenset({16, 19}))

TURNTABLE = Grammar("turntable", "ESG-LAB,TURNTABLE-TILT,0,1.0", [
    Cmd("AZ", (Real(0.0, 360.0, hi_open=True),)),
    Cmd("TILT", (Real(-90.0, 90.0),)),
    Cmd("AZ?", reply=r"[0-9]+\.[0-9]{4}"),
    Cmd("TILT?", reply=NUM + "{4}"),
    Cmd("LOCK"),
    Cmd("UNLOCK"),
    Cmd("STAT?", reply="HOLD|MOVING|LOCKED"),
], state_codes=frozenset({16, 18}))

THEODOLITE = Grammar("theodolite", "ESG-LAB,THEODOLITE,0,1.0", [
    Cmd("READ?", reply=NUM + "{2} " + NUM + "{2}"),
])

CONSOLE = Grammar("console", "ESG-LAB,GYRO-CONSOLE,0,1.0", [
    Cmd("SPIN", (Word(("UP", "OFF")),)),
    Cmd("DAMP", (Word(("ON", "OFF")),)),
    Cmd("STAT?", reply=r"SUSP [01] SPIN [0-9]+\.[0-9]{2} DAMP [01] VAC [0-9]\.[0-9]E[-+][0-9]+"),
    Cmd("SPEED?", reply=r"[0-9]+\.[0-9]{2}"),
    Cmd("LAMP", (Int(1, 3), Real(50.0, 150.0))),
    Cmd("LAMP?", (Int(1, 3),), reply=r"[0-9]+\.[0-9]"),
    Cmd("XLATE", (Int(1, 3), Real(-120.0, 120.0), Real(-120.0, 120.0))),
])

GRAMMARS = {g.name: g for g in (TABLE, PATCH_PANEL, COUNTER, AUTOCOLLIMATOR, BUBBLE_LEVELS,
                                OSCILLATOR, FIXTURE, DVM, GYRO_POWER, SETUP_AIDS, PROCESSOR, HEAD,
                                TURNTABLE, THEODOLITE, CONSOLE)}
