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
"""

from __future__ import annotations

import logging
import queue
import socket
import threading

from station.hil.can_hub import CanHub
from station.hil.status import LinkCounters, short

log = logging.getLogger(__name__)

GRACE_S = 0.2  # wall seconds a new raw-mode client may take to read its "< ok >"
MAX_QUEUED = 500_000  # messages (~30 MB) queued for a client that does not read: then dropped
_HOLD = object()


def format_frame(t: float, arbitration_id: int, data: bytes) -> str:
    """``< frame III SECONDS.USECS HEXDATA >`` for a standard data frame."""
    return f"< frame {arbitration_id & 0x7FF:03X} {max(t, 0.0):.6f} {data.hex().upper()} >"


def parse_send(tokens: list[str]) -> tuple[int, bytes]:
    """``send III L B0 ...`` tokens -> (identifier, data); ValueError if malformed or not ours."""
    if len(tokens) < 3:
        raise ValueError("send needs an identifier and a length")
    ident, dlc = tokens[1], int(tokens[2], 16)
    if len(ident) != 3:
        raise ValueError("extended frames do not exist on the IEU bus")
    data = bytes(int(b, 16) for b in tokens[3:])
    if dlc != len(data) or dlc > 8:
        raise ValueError(f"length {dlc} does not match {len(data)} data bytes")
    return int(ident, 16), data


class SocketcandClient:
    """One TCP connection: protocol state, a reader thread and a writer thread."""

    def __init__(self, server: SocketcandServer, sock: socket.socket, peer: str) -> None:
        self.server = server
        self.sock = sock
        self.peer = peer
        self.raw = False
        self.opened = False
        self.counters = LinkCounters()  # rx: reader thread; frames out: sim; bytes out: writer
        self._out: queue.Queue = queue.Queue(MAX_QUEUED)
        self._spoke = threading.Event()  # the client sent something after entering raw mode
        self._closed = threading.Event()
        self._reader = threading.Thread(target=self._read_loop, name=f"scd-rd-{peer}", daemon=True)
        self._writer = threading.Thread(target=self._write_loop, name=f"scd-wr-{peer}", daemon=True)

    def start(self) -> None:
        self._writer.start()
        self._say("< hi >")
        self._reader.start()

    # ----- output -----
    def _say(self, msg: str | object) -> None:
        try:
            self._out.put_nowait(msg)
        except queue.Full:
            log.warning("socketcand %s: client not reading, disconnecting it", self.peer)
            self.server.hub.detach(self)
            self._closed.set()
            try:
                self.sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def deliver(self, t: float, arbitration_id: int, data: bytes) -> None:
        """Simulation thread: queue a frame (only clients in raw mode are on the hub)."""
        self._say(format_frame(t, arbitration_id, data))
        self.counters.tx_msgs += 1

    def _write_loop(self) -> None:
        while True:
            item = self._out.get()
            batch: list[str] = []
            hold = False
            while True:
                if item is None:
                    break
                if item is _HOLD:
                    hold = True
                    break
                batch.append(item)
                if len(batch) >= 256:
                    break
                try:
                    item = self._out.get_nowait()
                except queue.Empty:
                    break
            if batch:
                out = "".join(batch).encode("ascii")
                try:
                    self.sock.sendall(out)
                except OSError:
                    self._closed.set()
                    return
                self.counters.tx_bytes += len(out)
                self.counters.touch()
            if item is None or self._closed.is_set():
                return
            if hold:
                self._spoke.wait(GRACE_S)

    # ----- input -----
    def _read_loop(self) -> None:
        buf = ""
        try:
            while not self._closed.is_set():
                try:
                    chunk = self.sock.recv(4096)
                except OSError:
                    break
                if not chunk:
                    break
                if self.raw:
                    self._spoke.set()
                self.counters.rx_bytes += len(chunk)
                self.counters.touch()
                buf += chunk.decode("ascii", "replace")
                while True:
                    start = buf.find("<")
                    end = buf.find(">", start + 1) if start >= 0 else -1
                    if start < 0:
                        buf = ""
                        break
                    if end < 0:
                        buf = buf[start:] if len(buf) - start < 1024 else ""
                        break
                    self._message(buf[start + 1 : end].split())
                    buf = buf[end + 1 :]
        finally:
            self.close()

    def _message(self, tokens: list[str]) -> None:
        if not tokens:
            return
        cmd = tokens[0]
        self.counters.last_msg = short(" ".join(tokens))
        if cmd == "echo":
            self._say("< echo >")
        elif not self.opened:
            if cmd == "open" and len(tokens) == 2 and tokens[1] == self.server.channel:
                self.opened = True
                self._say("< ok >")
            else:
                self._say("< error could not open bus >")
        elif cmd == "rawmode":
            self._say("< ok >")
            self._say(_HOLD)
            self.raw = True
            self.server.hub.attach(self)
        elif cmd == "bcmmode":
            self.server.hub.detach(self)
            self.raw = False
            self._say("< ok >")
        elif cmd == "send":
            try:
                ident, data = parse_send(tokens)
            except ValueError as e:
                log.info("socketcand %s: ignored %s: %s", self.peer, " ".join(tokens)[:40], e)
                return
            self.server.hub.send(self, ident, data)
            self.counters.rx_msgs += 1
        elif not self.raw:
            self._say("< error unsupported command >")
        else:  # an error message in raw mode would break python-can's frame parser
            log.info("socketcand %s: ignored %r in raw mode", self.peer, " ".join(tokens)[:40])

    # ----- teardown -----
    def close(self) -> None:
        self.server.hub.detach(self)
        self._closed.set()
        self._spoke.set()
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        try:
            self._out.put_nowait(None)
        except queue.Full:
            pass
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

    def snapshot(self) -> tuple[int, LinkCounters]:
        """(clients connected, counters summed over every client past and present)."""
        total = LinkCounters()
        with self._lock:
            total.add(self._retired)
            for c in self._clients:
                total.add(c.counters)
            return len(self._clients), total

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
