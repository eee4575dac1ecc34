"""The CAN servers' host parsers under random and mutated byte streams (hypothesis).

slcan (:class:`SlcanLines`, :class:`SlcanProtocol`) and socketcand
(:class:`SocketcandMessages`, :class:`SocketcandProtocol`) are fed streams of valid
commands, mutated commands and random bytes, in random chunks: nothing raises, the chunking
does not matter, every valid command embedded in the junk is still honoured with its exact
identifier and data, and refused input leaves the protocol state as it was. Examples are
bounded and derandomized, so the suite stays fast and repeatable.
"""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from station.hil import slcan, socketcand
from station.hil.slcan import ERROR, OK, SlcanLines, SlcanProtocol
from station.hil.socketcand import HOLD, SocketcandMessages, SocketcandProtocol

FAST = settings(max_examples=150, deadline=None, derandomize=True)

frames = st.tuples(st.integers(0, 0x7FF), st.binary(min_size=0, max_size=8))
junk_bytes = st.binary(min_size=0, max_size=80)


def chunked(data: bytes, cuts: list[int]) -> list[bytes]:
    """``data`` cut at the given positions (sorted, deduplicated, clipped)."""
    points = sorted({c % (len(data) + 1) for c in cuts} | {0, len(data)})
    return [data[a:b] for a, b in zip(points, points[1:], strict=False)]


def slcan_frame(ident: int, data: bytes) -> bytes:
    return f"t{ident:03X}{len(data)}{data.hex()}".encode()


def mutate(data: bytes, edits: list[tuple[int, int, int]]) -> bytes:
    """Apply (kind, position, byte) edits: 0 flip a byte, 1 delete, 2 insert."""
    out = bytearray(data)
    for kind, pos, value in edits:
        if not out and kind != 2:
            continue
        i = pos % (len(out) + (1 if kind == 2 else 0))
        if kind == 0:
            out[i] = value
        elif kind == 1:
            del out[i]
        else:
            out.insert(i, value)
    return bytes(out)


edits = st.lists(st.tuples(st.integers(0, 2), st.integers(0, 200), st.integers(0, 255)),
                 max_size=4)


# ----- slcan -----
class SlcanHost:
    """An SlcanProtocol with what reached the bus and the replies, fed through SlcanLines."""

    def __init__(self, opened: bool = True) -> None:
        self.bus: list[tuple[int, bytes]] = []
        self.closed = 0
        self.protocol = SlcanProtocol(lambda i, d: self.bus.append((i, d)), self._close)
        self.lines = SlcanLines()
        self.replies: list[bytes] = []
        if opened:
            self.protocol.execute(b"O")

    def _close(self) -> None:
        self.closed += 1

    def feed(self, data: bytes) -> None:
        for line in self.lines.feed(data):
            self.replies.append(self.protocol.execute(line))

    def state(self) -> tuple:
        p = self.protocol
        return p.is_open, p.listen_only, p.frames_sent, len(self.bus), self.closed


@FAST
@given(st.binary(max_size=300), st.lists(st.integers(0, 400), max_size=8))
def test_slcan_any_bytes_any_chunking(data, cuts):
    """Random bytes: no exception, one reply per line, the same whatever the chunking."""
    whole, pieces = SlcanHost(), SlcanHost()
    whole.feed(data)
    for c in chunked(data, cuts):
        pieces.feed(c)
    assert whole.replies == pieces.replies and whole.bus == pieces.bus
    assert all(r in (OK, ERROR, b"z\r", b"V1013\r", b"NSIM1\r", b"F00\r") for r in whole.replies)


@FAST
@given(st.lists(st.tuples(junk_bytes, frames), min_size=1, max_size=6),
       st.lists(st.integers(0, 800), max_size=10))
def test_slcan_valid_frames_survive_junk(items, cuts):
    """Junk lines (refused: no command starts with '#', or over-long) never cost a valid
    frame: each reaches the bus once, with its exact identifier and data."""
    stream = b""
    for junk, (ident, data) in items:
        junk = junk.replace(b"\r", b"").replace(b"\n", b"")
        stream += b"#" + junk + b"\r" + slcan_frame(ident, data) + b"\r"
    host = SlcanHost()
    for c in chunked(stream, cuts):
        host.feed(c)
    assert host.bus == [f for _, f in items]
    assert host.replies == [ERROR, b"z\r"] * len(items)


@FAST
@given(frames, st.binary(min_size=65, max_size=200), st.lists(st.integers(0, 400), max_size=6))
def test_slcan_over_long_line_is_refused_whole(frame, filler, cuts):
    """A line longer than MAX_LINE ending in a valid command executes nothing: one BEL."""
    filler = filler.replace(b"\r", b"x").replace(b"\n", b"x")
    for tail in (slcan_frame(*frame), b"C", b"V"):
        host = SlcanHost()
        before = host.state()
        for c in chunked(filler + tail + b"\rV\r", cuts):
            host.feed(c)
        assert host.replies == [ERROR, b"V1013\r"]
        assert host.state() == before


@FAST
@given(frames, edits, st.booleans())
def test_slcan_refused_input_changes_nothing(frame, edit, opened):
    """A mutated frame command is refused with BEL and changes nothing, or it is still a
    valid command and is honoured exactly as written."""
    host = SlcanHost(opened)
    line = mutate(slcan_frame(*frame), edit).replace(b"\r", b"").replace(b"\n", b"")
    before = host.state()
    host.feed(line + b"\r")
    (reply,) = host.replies
    if reply == ERROR:
        assert host.state() == before
    elif reply == b"z\r":
        text = line.decode("ascii").strip()
        assert host.bus == [(int(text[1:4], 16), bytes.fromhex(text[5:]))]
        assert len(text) == 5 + 2 * int(text[4]) and int(text[1:4], 16) <= 0x7FF
    else:
        assert host.bus == [] and host.protocol.frames_sent == 0


def test_slcan_examples():
    host = SlcanHost(opened=False)
    host.feed(b"t0802AB01\r")  # closed: refused
    host.feed(b"S6\rO\rt0802AB01\r")
    host.feed(b"t8002AB01\r")  # identifier beyond 7FF
    host.feed(b"t0802AB0\r" + b"t0801FF\r\n" + b"O1\rS6\rV\r")  # odd hex; ok; O takes
    assert host.replies == [ERROR, OK, OK, b"z\r", ERROR, ERROR, b"z\r", ERROR, ERROR,
                            b"V1013\r"]
    assert host.bus == [(0x080, b"\xab\x01"), (0x080, b"\xff")]
    assert slcan.format_frame(0x104, b"\x01\xff") == b"t104201FF\r"


# ----- socketcand -----
class ScdHost:
    """A SocketcandProtocol with its bus attachments, the frames it sent and its replies."""

    def __init__(self, raw: bool = True) -> None:
        self.attached = 0
        self.bus: list[tuple[int, bytes]] = []
        self.protocol = SocketcandProtocol("ieu", self._attach, self._detach,
                                           lambda i, d: self.bus.append((i, d)))
        self.messages = SocketcandMessages()
        self.replies: list[object] = []
        if raw:
            self.feed(b"< open ieu >< rawmode >")
            self.replies.clear()

    def _attach(self) -> None:
        self.attached += 1

    def _detach(self) -> None:
        self.attached -= 1

    def feed(self, data: bytes) -> None:
        for tokens in self.messages.feed(data):
            self.replies += self.protocol.handle(tokens)

    def state(self) -> tuple:
        p = self.protocol
        return p.opened, p.raw, self.attached, p.frames_sent, len(self.bus)


def scd_send(ident: int, data: bytes) -> bytes:
    """As python-can writes it: identifier 3 hex digits, length and bytes unpadded hex."""
    body = " ".join(f"{x:x}" for x in data)
    return f"< send {ident:03X} {len(data):X} {body} >".encode()


@FAST
@given(st.binary(max_size=400), st.lists(st.integers(0, 500), max_size=8))
def test_socketcand_any_bytes_any_chunking(data, cuts):
    whole, pieces = ScdHost(), ScdHost()
    whole.feed(data)
    for c in chunked(data, cuts):
        pieces.feed(c)
    assert whole.replies == pieces.replies and whole.bus == pieces.bus
    assert whole.attached == pieces.attached and whole.attached in (0, 1)


@FAST
@given(st.lists(st.tuples(junk_bytes, frames), min_size=1, max_size=6),
       st.lists(st.integers(0, 1200), max_size=10))
def test_socketcand_valid_sends_survive_junk(items, cuts):
    """Junk between messages (no '<' or '>' in it) never costs a valid send."""
    stream = b""
    for junk, frame in items:
        stream += junk.replace(b"<", b"").replace(b">", b"") + scd_send(*frame)
    host = ScdHost()
    for c in chunked(stream, cuts):
        host.feed(c)
    assert host.bus == [f for _, f in items]
    assert host.attached == 1


@FAST
@given(frames, edits)
def test_socketcand_refused_input_changes_nothing(frame, edit):
    """A mutated send is honoured exactly as written if still valid, else changes nothing."""
    msg = mutate(scd_send(*frame), edit)
    host = ScdHost()
    before = host.state()
    host.feed(msg + b">")  # closes any message the mutation left open
    if not host.bus:
        assert host.state() == before
        return
    (sent,) = host.bus
    text = msg.decode("ascii", "replace") + ">"
    start = text.index("<")
    inner = text[start + 1 : text.index(">", start)]
    assert socketcand.parse_send(inner.split()) == sent
    assert inner.split()[1] == f"{sent[0]:03X}" or int(inner.split()[1], 16) == sent[0]


@FAST
@given(st.integers(1, 5), frames)
def test_socketcand_rawmode_is_idempotent(n, frame):
    """rawmode n times: acknowledged each time, on the bus once, each frame sent once."""
    host = ScdHost(raw=False)
    host.feed(b"< open ieu >" + b"< rawmode >" * n + scd_send(*frame))
    assert host.replies == ["< ok >", "< ok >", HOLD] + ["< ok >"] * (n - 1)
    assert host.attached == 1 and host.bus == [frame]
    host.feed(b"< bcmmode >< bcmmode >")
    assert host.attached == 0


@FAST
@given(st.integers(socketcand.MAX_MESSAGE + 1, 3 * socketcand.MAX_MESSAGE), frames,
       st.lists(st.integers(0, 4000), max_size=8))
def test_socketcand_over_long_message_is_refused_whole(size, frame, cuts):
    """A message longer than MAX_MESSAGE with a valid send inside sends nothing."""
    inner = scd_send(*frame)[1:-1]  # without its < >
    stream = b"<" + b"x" * size + b"<" + inner + b">" + scd_send(*frame)
    host = ScdHost()
    for c in chunked(stream, cuts):
        host.feed(c)
    assert host.bus == [frame] and host.messages.refused == 1


def test_socketcand_parse_send_is_strict():
    ok = socketcand.parse_send("send 080 2 1 ff".split())
    assert ok == (0x080, b"\x01\xff")
    for bad in ("send 080 +2 1 ff", "send 080 0x2 1 ff", "send 080 2 1_0 ff", "send 800 0",
                "send 0800 0", "send 080 9 1 2 3 4 5 6 7 8 9", "send 080 2 1", "send 080 2 1 fff",
                "send 80 0", "send 080", "send 0x8 0", "send 080 1 -1"):
        try:
            socketcand.parse_send(bad.split())
        except ValueError:
            continue
        raise AssertionError(f"accepted {bad!r}")


def test_socketcand_before_open_and_in_raw_mode():
    host = ScdHost(raw=False)
    host.feed(b"< rawmode >< send 080 0 >< open can0 >< open ieu >< bogus >")
    assert host.replies == ["< error could not open bus >"] * 3 + \
        ["< ok >", "< error unsupported command >"]
    assert host.bus == [] and host.attached == 0
    host.feed(b"< rawmode >< bogus >< send 080 9 >< echo >")
    assert host.replies[-3:] == ["< ok >", HOLD, "< echo >"] and host.bus == []
