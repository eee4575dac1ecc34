"""Reply grammars of the serial instruments (docs/protocols.md): one regular expression per
reply form, built from the format each instrument prints with, and the physical range of
every number in it.

A driver checks a reply in two stages: :meth:`Form.matches` (syntax: field count, digits,
decimal point, sign, the exact spelling a Python format string gives) decides whether a
line *is* the reply it waits for; :meth:`Form.parse` then converts it and refuses a value
outside its range. ``float()`` and ``int()`` only ever see a token that already matched, so
``nan``, ``inf``, ``1_0``, ``+5`` or a lost decimal point never become numbers.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

# --------------------------------------------------------------------------- tokens

# str(int) of an integer: no sign but a minus, no leading zero (a line has at most 512 bytes)
_INT = r"(?:0|-?[1-9][0-9]{0,511})"


class OutOfRange(Exception):
    """A well-formed value outside its range (the driver turns it into ReadingOutOfRange)."""

    def __init__(self, what: str, value: float, lo: float | None, hi: float | None) -> None:
        self.what, self.value, self.lo, self.hi = what, value, lo, hi
        span = f"[{_num(lo)}, {_num(hi)}]"
        super().__init__(f"{what} {_num(value)} outside {span}")


class Malformed(Exception):
    """A line that is not of the form (the driver turns it into MalformedReply)."""


def _num(x: float | None) -> str:
    if x is None:
        return "-inf"
    return f"{x:g}" if isinstance(x, float) else str(x)


@dataclass(frozen=True)
class Field:
    """One space- (or comma-) separated token of a reply."""

    what: str  # what the value is, for messages: "azimuth, deg"
    pattern: str  # regex of the token, non-capturing groups only
    syntax: str  # the token as the protocol writes it: "[-]d.ddddddd"
    convert: Callable[[str], Any] = str
    lo: float | None = None
    hi: float | None = None
    canonical: Callable[[str], bool] | None = None  # extra exactness check of the token
    literal: bool = False  # a keyword of the reply, not a value

    def value(self, token: str) -> Any:
        v = self.convert(token)
        if (self.lo is not None and v < self.lo) or (self.hi is not None and v > self.hi):
            raise OutOfRange(self.what, v, self.lo, self.hi)
        return v


def fixed(what: str, decimals: int, lo: float, hi: float) -> Field:
    """A number printed with ``f"{v:.{decimals}f}"`` (decimals >= 1): optional minus, no
    leading zeros, a decimal point and exactly ``decimals`` digits after it; the round trip
    through the format refuses digits a double cannot carry."""
    fmt = f".{decimals}f"
    return Field(what, r"-?(?:0|[1-9][0-9]{0,511})" + rf"\.[0-9]{{{decimals}}}",
                 "[-]d." + "d" * decimals, float, lo, hi,
                 canonical=lambda t: format(float(t), fmt) == t)


def integer(what: str, lo: int, hi: int) -> Field:
    """An integer printed with ``str(n)``: optional minus (never ``-0``), no leading zeros.
    The sign and the digit count are the range's business, not the syntax's."""
    return Field(what, _INT, "[-]d" if lo < 0 else "d", int, lo, hi)


def _is_g(token: str) -> bool:
    return format(float(token), "g") == token


def general(what: str, lo: float, hi: float) -> Field:
    """A number printed with ``f"{v:g}"`` (six significant digits, no trailing zeros, an
    exponent beyond 1e-5..1e6): the regex admits the shapes, the round trip the exact text."""
    mant = r"(?:0|[1-9][0-9]{0,5})(?:\.[0-9]{0,9}[1-9])?"  # 0.000123457: 3 zeros, 6 digits
    pattern = rf"-?(?:{mant}|[1-9](?:\.[0-9]{{0,4}}[1-9])?e[-+][0-9]{{2,3}})"
    return Field(what, pattern, "%g", float, lo, hi, canonical=_is_g)


def _is_e1(token: str) -> bool:
    return format(float(token), ".1E") == token


def scientific(what: str, lo: float, hi: float) -> Field:
    """A number printed with ``f"{v:.1E}"``: ``[-]d.dE[+-]dd`` (the sign is the range's
    business)."""
    return Field(what, r"-?[0-9]\.[0-9]E[-+][0-9]{2,3}", "d.dE+dd", float, lo, hi,
                 canonical=_is_e1)


def word(what: str, *choices: str) -> Field:
    """One of a fixed set of words."""
    return Field(what, "(?:" + "|".join(re.escape(c) for c in choices) + ")",
                 "|".join(choices))


def literal(text: str) -> Field:
    """A keyword the reply always carries at this place (``SUSP`` in the console's STAT?)."""
    return Field(text, re.escape(text), text, literal=True)


def flag(what: str) -> Field:
    """``0`` or ``1``, as a bool."""
    return Field(what, "[01]", "0|1", lambda t: t == "1")


# --------------------------------------------------------------------------- forms


class Form:
    """One reply form: fields in order, separated by exactly one ``sep``."""

    def __init__(self, fields: Sequence[Field], sep: str = " ", name: str | None = None):
        self.fields = tuple(fields)
        self.sep = sep
        self._re = re.compile(re.escape(sep).join(f"({f.pattern})" for f in self.fields),
                              re.ASCII)
        self.name = name or sep.join(f.syntax if f.literal else f"<{f.what}: {f.syntax}>"
                                     for f in self.fields)
        self._last: tuple[str | None, tuple[str, ...] | None] = (None, None)

    def tokens(self, text: str) -> tuple[str, ...] | None:
        last = self._last  # a driver's reply is matched, then parsed: the same text twice
        if last[0] == text:
            return last[1]
        toks: tuple[str, ...] | None = None
        m = self._re.fullmatch(text)
        if m is not None:
            toks = m.groups()
            for f, t in zip(self.fields, toks, strict=True):
                if f.canonical is not None and not f.canonical(t):
                    toks = None
                    break
        self._last = (text, toks)  # one tuple: read and written whole
        return toks

    def matches(self, text: str) -> bool:
        """``text`` has this form exactly (values not yet checked against their ranges)."""
        return self.tokens(text) is not None

    def parse(self, text: str) -> tuple[Any, ...]:
        """The values of a line of this form (keywords left out); Malformed or OutOfRange."""
        toks = self.tokens(text)
        if toks is None:
            raise Malformed(f"{text!r} is not {self.name}")
        return tuple(f.value(t) for f, t in zip(self.fields, toks, strict=True)
                     if not f.literal)


class OneOf:
    """Alternative forms of one reply (``OFF`` or ``ON <s>``); parse gives (index, values)."""

    def __init__(self, *forms: Form) -> None:
        self.forms = forms
        self.name = " or ".join(f.name for f in forms)

    def matches(self, text: str) -> bool:
        return any(f.matches(text) for f in self.forms)

    def parse(self, text: str) -> tuple[int, tuple[Any, ...]]:
        for i, f in enumerate(self.forms):
            if f.matches(text):
                return i, f.parse(text)
        raise Malformed(f"{text!r} is not {self.name}")


class ListForm:
    """A separated list of one field (``LINES?``), each item once, ``lo``..``hi`` items."""

    def __init__(self, item: Field, sep: str = ",", lo: int = 1, hi: int = 256) -> None:
        self.item, self.sep, self.lo, self.hi = item, sep, lo, hi
        self._re = re.compile(f"(?:{item.pattern})(?:{re.escape(sep)}(?:{item.pattern}))*",
                              re.ASCII)
        self.name = f"<{item.what}>{sep}... ({lo} to {hi}, each once)"

    def matches(self, text: str) -> bool:
        if self._re.fullmatch(text) is None:
            return False
        items = text.split(self.sep)
        return self.lo <= len(items) <= self.hi and len(set(items)) == len(items)

    def parse(self, text: str) -> list[Any]:
        if not self.matches(text):
            raise Malformed(f"{text!r} is not {self.name}")
        return [self.item.value(t) for t in text.split(self.sep)]


ReplyForm = Form | OneOf | ListForm

# --------------------------------------------------------------------------- common replies

OK = Form([literal("OK")])
PASS = Form([literal("PASS")])
# ERR <code> <text>: the refusal every instrument gives (docs/protocols.md, common rules)
ERR = re.compile(r"ERR (0|-?[1-9][0-9]{0,3})(?: ([ -~]*))?", re.ASCII)
# maker,model,unit,version of any instrument (station check does not know the model)
_FIELD = r"[\x20-\x2b\x2d-\x7e]"  # printable ASCII but the comma
ANY_IDENTITY = re.compile(rf"{_FIELD}+,{_FIELD}+,{_FIELD}*,[0-9]+(?:\.[0-9]+)*", re.ASCII)


def identity(maker: str, model: str, unit: str = r"[A-Za-z0-9]+") -> re.Pattern[str]:
    """The ``*IDN?`` reply of one kind of instrument: its maker and model, any unit and
    version (``ISU-LAB,FC-1,C3,1.0``)."""
    return re.compile(rf"{re.escape(maker)},{re.escape(model)},{unit},[0-9]+(?:\.[0-9]+)*",
                      re.ASCII)


def angle_between(az1: float, zen1: float, az2: float, zen2: float) -> float:
    """Angle, deg, between two directions given as (azimuth, zenith) in degrees."""
    a1, z1, a2, z2 = (math.radians(x) for x in (az1, zen1, az2, zen2))
    # haversine (zenith = colatitude): accurate for the small angles that matter here
    h = math.sin((z1 - z2) / 2) ** 2 + math.sin(z1) * math.sin(z2) * math.sin((a1 - a2) / 2) ** 2
    return math.degrees(2 * math.asin(min(1.0, math.sqrt(max(h, 0.0)))))
