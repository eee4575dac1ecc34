"""Fuzz targets of the served rack's CAN servers: the slcan adapter and the socketcand
server, fed random and mutated host byte streams in random chunks (``python bench/fuzz.py
N --only hil``).

Each input is a stream of a few commands: valid ones (as python-can writes them), mutated
ones, junk, over-long lines or messages, cut into random chunks and fed to a fresh parser
(``SlcanLines`` + ``SlcanProtocol``, ``SocketcandMessages`` + ``SocketcandProtocol``).
What the parser did (replies, frames put on the bus, whether the client is on the bus) is
compared with a reference written here from the protocol's rules (regular expressions over
the whole stream, independent of the parser's code). Outcome: ``wrong`` if they differ (a
malformed command honoured, a valid one refused or altered); else ``rejected`` if the
stream held a malformed command (refused as it should be), ``accepted`` if not.
"""

from __future__ import annotations

import random
import re

from fuzz_core import FuzzTarget

from station.hil import slcan, socketcand

# ----- slcan -----
SLCAN_MAX = slcan.MAX_LINE
_S_FRAME = re.compile(r"t([0-9A-Fa-f]{3})([0-8])([0-9A-Fa-f]*)")
_HEX4 = re.compile(r"[0-9A-Fa-f]{4}")
_HEX8 = re.compile(r"[0-9A-Fa-f]{8}")
BEL, CR = b"\a", b"\r"


class SlcanReference:
    """The adapter as the Lawicel rules (module doc of station.hil.slcan) describe it."""

    def __init__(self) -> None:
        self.open = False
        self.listen = False
        self.bus: list[tuple[int, bytes]] = []

    def line(self, raw: bytes) -> bytes:
        if len(raw) > SLCAN_MAX or any(b < 0x20 or b > 0x7E for b in raw):
            return BEL
        s = raw.decode().strip()
        if s == "":
            return CR
        if s in ("O", "L"):
            self.open, self.listen = True, s == "L"
            return CR
        if s == "C":
            self.open = self.listen = False
            return CR
        if s in ("V", "N", "F"):
            return {"V": b"V1013\r", "N": b"NSIM1\r", "F": b"F00\r"}[s]
        if re.fullmatch(r"[SY][0-9]", s) or (s[0] == "s" and _HEX4.fullmatch(s[1:])):
            return BEL if self.open else CR
        if re.fullmatch(r"[ZXQW][012]", s) or (s[0] in "Mm" and _HEX8.fullmatch(s[1:])):
            return CR
        m = _S_FRAME.fullmatch(s)
        if m and self.open and not self.listen:
            ident, n, data = int(m.group(1), 16), int(m.group(2)), m.group(3)
            if ident <= 0x7FF and len(data) == 2 * n:
                self.bus.append((ident, bytes.fromhex(data)))
                return b"z\r"
        return BEL


def _slcan_valid(rng: random.Random) -> bytes:
    kind = rng.randrange(6)
    if kind <= 2:
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(9)))
        s = f"t{rng.randrange(0x800):03X}{len(data)}{data.hex()}"
        return (s.lower() if rng.random() < 0.2 else s).encode()
    return rng.choice([b"O", b"C", b"S6", b"V", b"N", b"F", b"", b"L", b"Z0", b"M00000000"])


def _mutate(rng: random.Random, data: bytes, alphabet: bytes) -> bytes:
    out = bytearray(data)
    for _ in range(rng.randrange(1, 4)):
        kind = rng.randrange(3)
        if kind == 2 or not out:
            out.insert(rng.randrange(len(out) + 1), rng.choice(alphabet))
        elif kind == 1:
            del out[rng.randrange(len(out))]
        else:
            out[rng.randrange(len(out))] = rng.choice(alphabet)
    return bytes(out)


_SLCAN_ALPHABET = b"tTrOCLSsVNFZ0123456789ABCDEFabcdefgxyz \x00\xff\x7f"


def _slcan_line(rng: random.Random) -> tuple[bytes, bool]:
    """(a command line without terminator, whether it is a valid command as generated)."""
    r = rng.random()
    if r < 0.45:
        return _slcan_valid(rng), True
    if r < 0.8:
        return _mutate(rng, _slcan_valid(rng), _SLCAN_ALPHABET), False
    if r < 0.9:
        n = rng.randrange(SLCAN_MAX + 1, 3 * SLCAN_MAX)
        return bytes(rng.choice(b"x0t") for _ in range(n)) + _slcan_valid(rng), False
    return bytes(rng.randrange(256) for _ in range(rng.randrange(1, 40))), False


def _chunks(rng: random.Random, data: bytes) -> list[bytes]:
    cuts = sorted({rng.randrange(len(data) + 1) for _ in range(rng.randrange(6))})
    points = [0, *cuts, len(data)]
    return [data[a:b] for a, b in zip(points, points[1:], strict=False)]


def run_slcan(rng: random.Random) -> str:
    lines = []
    all_valid = True
    for _ in range(rng.randrange(1, 8)):
        line, valid = _slcan_line(rng)
        line = line.replace(b"\r", b"").replace(b"\n", b"")
        lines.append(line)
        all_valid &= valid
    stream = b""
    for line in lines:
        end = rng.choice([b"\r", b"\n", b"\r\n"])
        if not line and stream.endswith(b"\r") and end.startswith(b"\n"):
            end = b"\r"  # CR then LF is one line end, not an empty line
        stream += line + end
    ref = SlcanReference()
    if rng.random() < 0.7:
        lines.insert(0, b"O")
        stream = b"O\r\n" + stream
    want = [ref.line(line) for line in lines]
    bus: list[tuple[int, bytes]] = []
    proto = slcan.SlcanProtocol(lambda i, d: bus.append((i, d)))
    splitter = slcan.SlcanLines()
    got = [proto.execute(line) for c in _chunks(rng, stream) for line in splitter.feed(c)]
    if got != want or bus != ref.bus or proto.is_open != ref.open:
        return "wrong"
    return "accepted" if all_valid and BEL not in want else "rejected"


# ----- socketcand -----
SCD_MAX = socketcand.MAX_MESSAGE
_SEND = re.compile(r"send ([0-9A-Fa-f]{3}) ([0-8])((?: [0-9A-Fa-f]{1,2})*)")


class SocketcandReference:
    """The server's side of python-can's socketcand conversation, from the protocol."""

    def __init__(self) -> None:
        self.opened = False
        self.raw = False
        self.bus: list[tuple[int, bytes]] = []
        self.replies: list[str] = []  # "< error ... >" recorded as "error"

    def stream(self, text: str) -> None:
        i = 0
        while True:
            start = text.find("<", i)
            if start < 0:
                return
            end = text.find(">", start + 1)
            if end < 0:
                return
            body = text[start + 1 : end]
            if len(body) <= SCD_MAX:
                self.message(" ".join(body.split()))
            i = end + 1

    def message(self, m: str) -> None:
        if m == "":
            return
        if m == "echo":
            self.replies.append("< echo >")
        elif not self.opened:
            if m == "open ieu":
                self.opened = True
                self.replies.append("< ok >")
            else:
                self.replies.append("error")
        elif m == "rawmode":
            self.raw = True
            self.replies.append("< ok >")
        elif m == "bcmmode":
            self.raw = False
            self.replies.append("< ok >")
        elif (s := _SEND.fullmatch(m)) and int(s.group(1), 16) <= 0x7FF and \
                len(s.group(3).split()) == int(s.group(2)):
            self.bus.append((int(s.group(1), 16), bytes(int(b, 16) for b in s.group(3).split())))
        elif not self.raw:
            self.replies.append("error")


def _scd_valid(rng: random.Random) -> bytes:
    if rng.random() < 0.7:
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(9)))
        body = " ".join(f"{x:x}" for x in data)
        return f"< send {rng.randrange(0x800):03X} {len(data):X} {body} >".encode()
    return rng.choice([b"< echo >", b"< rawmode >", b"< bcmmode >", b"< open ieu >"])


_SCD_ALPHABET = b"<> sendrawmodeb0123456789ABCDEFabcdefxyz\x00\xff"


def run_socketcand(rng: random.Random) -> str:
    parts = [b"< open ieu >"] if rng.random() < 0.8 else []
    if parts and rng.random() < 0.8:
        parts.append(b"< rawmode >")
    all_valid = True
    for _ in range(rng.randrange(1, 8)):
        r = rng.random()
        if r < 0.45:
            parts.append(_scd_valid(rng))
        elif r < 0.8:
            parts.append(_mutate(rng, _scd_valid(rng), _SCD_ALPHABET))
            all_valid = False
        elif r < 0.9:
            parts.append(b"<" + b"x" * rng.randrange(SCD_MAX - 2, 2 * SCD_MAX) + _scd_valid(rng))
            all_valid = False
        else:
            parts.append(bytes(rng.randrange(256) for _ in range(rng.randrange(1, 40))))
            all_valid = False
    stream = b"".join(parts)
    ref = SocketcandReference()
    ref.stream(stream.decode("ascii", "replace"))
    bus: list[tuple[int, bytes]] = []
    attached = [0]

    def attach() -> None:
        attached[0] += 1

    def detach() -> None:
        attached[0] -= 1

    proto = socketcand.SocketcandProtocol("ieu", attach, detach, lambda i, d: bus.append((i, d)))
    splitter = socketcand.SocketcandMessages()
    got: list[str] = []
    for c in _chunks(rng, stream):
        for tokens in splitter.feed(c):
            for r in proto.handle(tokens):
                if r is not socketcand.HOLD:
                    got.append("error" if str(r).startswith("< error") else str(r))
    if got != ref.replies or bus != ref.bus or attached[0] != int(ref.raw) \
            or proto.raw != ref.raw:
        return "wrong"
    return "accepted" if all_valid else "rejected"


TARGETS = [
    FuzzTarget("hil.slcan (lines + commands)", run_slcan),
    FuzzTarget("hil.socketcand (messages)", run_socketcand),
]
