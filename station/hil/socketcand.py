"""A socketcand-protocol TCP server on loopback, for python-can's ``interface="socketcand"``.

What python-can's client expects (can/interfaces/socketcand/socketcand.py): on connect the
server says ``< hi >``; the client sends ``< open CHANNEL >`` and ``< rawmode >``, each
answered ``< ok >`` in a message of its own (the client compares whole reads). In raw mode
the client sends ``< send IIII L B0 B1 ... >`` (hex, bytes unpadded) and receives
``< frame III SECONDS.USECS HEXDATA >``; a 3-digit identifier means a standard frame.
Timestamps are simulated seconds. Several clients may be connected at once (a sniffer next
to a procedure). Frames for a client that has just entered raw mode are held back until it
speaks or a short grace period passes, so they never share a read with its ``< ok >``.
Each client counts (display only) the frames it sent and was sent and the bytes both ways;
``SocketcandServer.snapshot()`` sums them, with the totals of clients gone.

:class:`SocketcandMessages` (bytes -> messages) and :class:`SocketcandProtocol` (state and
replies) are free of threads and I/O, so they are tested and fuzzed on their own. A second
``< rawmode >`` is acknowledged and changes nothing (the client is on the bus once). A
refused message is logged at most once a second per client, with a count of the rest.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections import deque
from collections.abc import Callable

from station.hil import throttle
from station.hil.can_hub import CanHub
from station.hil.counters import LinkCounters, short

log = logging.getLogger(__name__)

GRACE_S = 0.2  # wall seconds a new raw-mode client may take to read its "< ok >"
MAX_QUEUED = 65_536  # messages (~4 MB) queued for a client that does not read: then dropped
MAX_MESSAGE = 1024  # characters between "<" and ">"; a longer message is refused whole
MAX_BACKLOG = 256  # host frames posted to the simulation thread and not yet applied
MAX_CLIENTS = 16  # connections served at once (a procedure, sniffers, a spare)
HOLD = object()  # in a reply list: hold frames back until the client speaks (see module doc)
_HEX = frozenset("0123456789abcdefABCDEF")


def format_frame(t: float, arbitration_id: int, data: bytes) -> str:
    """``< frame III SECONDS.USECS HEXDATA >`` for a standard data frame."""
    return f"< frame {arbitration_id & 0x7FF:03X} {max(t, 0.0):.6f} {data.hex().upper()} >"


def _hex_token(tok: str, width: int) -> int:
    if not 1 <= len(tok) <= width or not set(tok) <= _HEX:
        raise ValueError(f"'{tok[:12]}' is not {width} hex digits")
    return int(tok, 16)


def parse_send(tokens: list[str]) -> tuple[int, bytes]:
    """``send III L B0 ...`` tokens -> (identifier, data); ValueError if malformed or not ours.

    The identifier is three hex digits up to 7FF (an eight-digit one is an extended frame,
    which the IEU bus does not carry), the length one hex digit 0..8, then that many data
    bytes of one or two hex digits (python-can writes them unpadded)."""
    if len(tokens) < 3 or tokens[0] != "send":
        raise ValueError("send needs an identifier and a length")
    ident_tok, dlc_tok, data_toks = tokens[1], tokens[2], tokens[3:]
    if len(ident_tok) != 3:
        raise ValueError("extended frames do not exist on the IEU bus")
    ident = _hex_token(ident_tok, 3)
    if ident > 0x7FF:
        raise ValueError(f"identifier {ident_tok} is beyond 7FF")
    dlc = _hex_token(dlc_tok, 1)
    data = bytes(_hex_token(b, 2) for b in data_toks)
    if dlc != len(data) or dlc > 8:
        raise ValueError(f"length {dlc_tok} does not match {len(data)} data bytes")
    return ident, data


class SocketcandMessages:
    """Host bytes -> the token lists of its ``< ... >`` messages. Text outside a message is
    dropped; a message longer than ``MAX_MESSAGE`` characters is refused whole (nothing up
    to its ``>`` is taken), however its bytes arrive; non-ASCII bytes never form a token."""

    def __init__(self) -> None:
        self._msg: list[str] | None = None  # inside a message: its characters so far
        self._size = 0
        self._discarding = False
        self.refused = 0  # over-long messages

    def feed(self, data: bytes) -> list[list[str]]:
        out: list[list[str]] = []
        text = data.decode("ascii", "replace")
        i, n = 0, len(text)
        while i < n:
            if self._msg is None and not self._discarding:
                j = text.find("<", i)
                if j < 0:
                    break
                self._msg, self._size, i = [], 0, j + 1
                continue
            j = text.find(">", i)
            piece = text[i:] if j < 0 else text[i:j]
            if not self._discarding:
                assert self._msg is not None
                self._size += len(piece)
                if self._size > MAX_MESSAGE:
                    self._msg, self._discarding = None, True
                    self.refused += 1
                else:
                    self._msg.append(piece)
            if j < 0:
                break
            if not self._discarding and self._msg is not None:
                out.append("".join(self._msg).split())
            self._msg, self._discarding, i = None, False, j + 1
        return out


class SocketcandProtocol:
    """One client's protocol state and the replies to its messages (free of I/O).

    ``attach()``/``detach()`` put the client on the bus or take it off, ``send(id, data)``
    puts a host frame on the bus. ``handle`` returns the messages to queue for the client
    (``HOLD``: hold frames back until it speaks)."""

    def __init__(self, channel: str, attach: Callable[[], None], detach: Callable[[], None],
                 send: Callable[[int, bytes], None]) -> None:
        self.channel = channel
        self._attach, self._detach, self._send = attach, detach, send
        self.opened = False
        self.raw = False
        self.frames_sent = 0
        self.refused: list[str] = []  # why the last message was refused (for the log)

    def handle(self, tokens: list[str]) -> list[str | object]:
        self.refused.clear()
        if not tokens:
            return []
        cmd = tokens[0]
        if cmd == "echo":
            return ["< echo >"] if len(tokens) == 1 else self._refuse("echo takes nothing")
        if not self.opened:
            if cmd == "open" and len(tokens) == 2 and tokens[1] == self.channel:
                self.opened = True
                return ["< ok >"]
            return ["< error could not open bus >"]
        if cmd == "rawmode" and len(tokens) == 1:
            if self.raw:  # already on the bus: acknowledge, never attach twice
                return ["< ok >"]
            self.raw = True
            self._attach()
            return ["< ok >", HOLD]
        if cmd == "bcmmode" and len(tokens) == 1:
            if self.raw:
                self._detach()
                self.raw = False
            return ["< ok >"]
        if cmd == "send":
            try:
                ident, data = parse_send(tokens)
            except ValueError as e:
                return self._refuse(str(e))
            self._send(ident, data)
            self.frames_sent += 1
            return []
        if not self.raw:
            return ["< error unsupported command >"]
        # an error message in raw mode would break python-can's frame parser
        return self._refuse("not a raw-mode command")

    def _refuse(self, why: str) -> list[str | object]:
        self.refused.append(why)
        return [] if self.raw else ["< error " + why.replace(">", ")").replace("<", "(") + " >"]


class SocketcandClient:
    """One TCP connection: protocol state, a reader thread and a writer thread.

    The reader takes the host's bytes at the CAN bus's pace (``throttle.SOCKETCAND_BYTES``
    and ``SOCKETCAND_FRAMES``: a socketcand box cannot put more on a 1 Mbit/s bus) and
    stops reading while ``MAX_BACKLOG`` frames wait for the simulation thread; the host's
    excess stays in the TCP buffers."""

    def __init__(self, server: SocketcandServer, sock: socket.socket, peer: str) -> None:
        self.server = server
        self.sock = sock
        self.peer = peer
        self.protocol = SocketcandProtocol(
            server.channel, lambda: server.hub.attach(self), lambda: server.hub.detach(self),
            lambda i, d: self._post(i, d))
        self.messages = SocketcandMessages()
        self.counters = LinkCounters()  # rx: reader thread; frames out: sim; bytes out: lock
        speed = server.hub.env.speed
        now = time.monotonic()
        self._bytes = throttle.TokenBucket.of(throttle.SOCKETCAND_BYTES, speed, now)
        self._frames = throttle.TokenBucket.of(throttle.SOCKETCAND_FRAMES, speed, now)
        self._slice = throttle.SOCKETCAND_BYTES.slice
        self.posted = 0  # host frames handed to the simulation thread (reader thread)
        self.applied = 0  # of those, frames on the bus (simulation thread)
        self.held = 0  # times the reader waited (bus busy, simulation behind)
        self.refusals = throttle.LogLimiter(log)  # reader thread
        self._backlog: deque[str | object] = deque()  # messages waiting for the writer
        self._busy = False  # the writer is sending (or holding): no direct sends meanwhile
        self._out_cond = threading.Condition()
        self._spoke = threading.Event()  # the client sent something after entering raw mode
        self._closed = threading.Event()
        self._reader = threading.Thread(target=self._read_loop, name=f"scd-rd-{peer}", daemon=True)
        self._writer = threading.Thread(target=self._write_loop, name=f"scd-wr-{peer}", daemon=True)

    @property
    def raw(self) -> bool:
        return self.protocol.raw

    def start(self) -> None:
        self._writer.start()
        self._say("< hi >")
        self._reader.start()

    # ----- output -----
    def _say(self, msg: str | object) -> None:
        """A message for the client (any thread). Sent at once from the calling thread when
        nothing is queued or being written (a frame then costs one non-blocking send, not a
        hand-over to the writer thread); otherwise queued, up to ``MAX_QUEUED``."""
        with self._out_cond:
            if self._closed.is_set():
                return
            if isinstance(msg, str) and not self._backlog and not self._busy:
                data = msg.encode("ascii")
                self.counters.tx_bytes += len(data)  # first: it may reach the host at once
                self.counters.touch()
                try:
                    n = self.sock.send(data, socket.MSG_DONTWAIT)
                except BlockingIOError:
                    n = 0
                except OSError:
                    self._closed.set()
                    self._out_cond.notify()
                    return
                if n == len(data):
                    return
                self.counters.tx_bytes -= len(data) - n  # the writer counts the rest
                msg = data[n:].decode("ascii")
            if len(self._backlog) >= MAX_QUEUED:
                log.warning("socketcand %s: client not reading, disconnecting it", self.peer)
                self.server.hub.detach(self)
                self._closed.set()
                self._out_cond.notify()
                try:
                    self.sock.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
                return
            self._backlog.append(msg)
            self._out_cond.notify()

    def deliver(self, t: float, arbitration_id: int, data: bytes) -> None:
        """Simulation thread: a frame for the client (only clients in raw mode are on the
        hub)."""
        self.counters.tx_msgs += 1  # counted first: the frame may reach the host at once
        self._say(format_frame(t, arbitration_id, data))

    def _write_loop(self) -> None:
        """Send what backed up, in batches; after a HOLD wait for the client to speak."""
        while True:
            with self._out_cond:
                while not self._backlog and not self._closed.is_set():
                    self._out_cond.wait()
                if self._closed.is_set():
                    return
                batch: list[str] = []
                hold = False
                while self._backlog and len(batch) < 256:
                    item = self._backlog.popleft()
                    if item is HOLD:
                        hold = True
                        break
                    batch.append(str(item))
                self._busy = True
            try:
                if batch:
                    out = "".join(batch).encode("ascii")
                    self.sock.sendall(out)
                    with self._out_cond:
                        self.counters.tx_bytes += len(out)
                        self.counters.touch()
                if hold:
                    self._spoke.wait(GRACE_S)
            except OSError:
                self._closed.set()
                return
            finally:
                with self._out_cond:
                    self._busy = False

    # ----- input -----
    def _post(self, ident: int, data: bytes) -> None:
        """Reader thread: a host frame onto the bus (at its arrival's simulated time)."""
        self.posted += 1
        self.counters.rx_msgs += 1
        self.server.hub.send(self, ident, data, self._applied)

    def _applied(self) -> None:
        self.applied += 1

    def _admitted(self) -> int:
        """Reader thread: bytes the link takes now (waits while the bus is busy)."""
        while not self._closed.is_set():
            now = time.monotonic()
            if self.posted - self.applied >= MAX_BACKLOG:
                wait = 0.002
            else:
                wait = max(self._bytes.wait_s(min(64, self._slice), now),
                           self._frames.wait_s(1, now))
            if wait <= 0:
                return min(self._slice, int(self._bytes.available(now)))
            self.held += 1
            self._closed.wait(wait)
        return 0

    def _read_loop(self) -> None:
        try:
            while not self._closed.is_set():
                n = self._admitted()
                if n <= 0:
                    break
                try:
                    chunk = self.sock.recv(n)
                except OSError:
                    break
                if not chunk:
                    break
                now = time.monotonic()
                self._bytes.take(len(chunk), now)
                if self.protocol.raw:
                    self._spoke.set()
                self.counters.rx_bytes += len(chunk)
                self.counters.touch()
                for tokens in self.messages.feed(chunk):
                    self._frames.take(1, now)
                    self._message(tokens)
        finally:
            self.close()

    def _message(self, tokens: list[str]) -> None:
        if not tokens:
            return
        self.counters.last_msg = short(" ".join(tokens))
        with self._out_cond:  # (reentrant) a frame delivered meanwhile queues behind the replies
            for reply in self.protocol.handle(tokens):
                self._say(reply)
        if self.protocol.refused:
            self.refusals.info(time.monotonic(), "socketcand %s: ignored %s: %s", self.peer,
                               " ".join(tokens)[:40], self.protocol.refused[0])

    # ----- teardown -----
    def close(self) -> None:
        self.server.hub.detach(self)
        self._closed.set()
        self._spoke.set()
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        with self._out_cond:
            self._out_cond.notify_all()  # the writer sees _closed and ends
        if self._writer.is_alive() and threading.current_thread() is not self._writer:
            self._writer.join(2.0)
        self.sock.close()
        self.server._forget(self)

    def join(self, timeout: float) -> None:
        if self._reader.is_alive() and threading.current_thread() is not self._reader:
            self._reader.join(timeout)


class SocketcandServer:
    """Serves one CAN channel of the hub to any number of socketcand clients."""

    def __init__(self, hub: CanHub, channel: str, host: str = "127.0.0.1", port: int = 0):
        self.hub = hub
        self.channel = channel
        self._listener = socket.create_server((host, port), reuse_port=False)
        self.host, self.port = self._listener.getsockname()[:2]
        self._clients: set[SocketcandClient] = set()
        self._retired = LinkCounters()  # totals of the clients gone (under the lock)
        self._retired_held = 0
        self._lock = threading.Lock()
        self._closing = False
        self._thread = threading.Thread(target=self._accept_loop, name="scd-accept", daemon=True)

    @property
    def address(self) -> str:
        return f"socketcand://{self.host}:{self.port}/{self.channel}"

    def start(self) -> None:
        self._thread.start()

    def _accept_loop(self) -> None:
        while True:
            try:
                sock, addr = self._listener.accept()
            except OSError:
                return  # listener closed
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._lock:
                full = len(self._clients) >= MAX_CLIENTS
            if full:  # each client costs two threads: refuse, as a busy socketcand would
                log.warning("socketcand: %d clients already, refusing %s:%s", MAX_CLIENTS,
                            *addr[:2])
                try:
                    sock.sendall(b"< error too many clients >")
                except OSError:
                    pass
                sock.close()
                continue
            client = SocketcandClient(self, sock, f"{addr[0]}:{addr[1]}")
            with self._lock:
                if self._closing:
                    sock.close()
                    return
                self._clients.add(client)
            client.start()

    def _forget(self, client: SocketcandClient) -> None:
        with self._lock:
            if client in self._clients:
                self._clients.discard(client)
                self._retired.add(client.counters)
                self._retired_held += client.held

    def snapshot(self) -> tuple[int, LinkCounters]:
        """(clients connected, counters summed over every client past and present)."""
        total = LinkCounters()
        with self._lock:
            total.add(self._retired)
            for c in self._clients:
                total.add(c.counters)
            return len(self._clients), total

    @property
    def held(self) -> int:
        """Times any client's input waited for the bus or the simulation (display)."""
        with self._lock:
            return self._retired_held + sum(c.held for c in self._clients)

    @property
    def clients(self) -> int:
        with self._lock:
            return len(self._clients)

    def close(self) -> None:
        with self._lock:
            self._closing = True
            clients = list(self._clients)
        try:
            self._listener.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._listener.close()
        self._thread.join(2.0)
        for c in clients:
            c.close()
            c.join(2.0)
