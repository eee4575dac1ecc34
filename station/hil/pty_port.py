"""A raw pty served to one client at a time: the server owns the master, clients open the slave.

The slave fd stays open in the server, otherwise reads on the master raise EIO while no
client is connected (DESIGN.md). A stable symlink names the slave device. Input is read by
a reader thread and handed to ``on_input``; output is written by a writer thread from a
bounded buffer, because the master-to-slave buffer holds only about 20 KiB and the thread
that must keep reading can never be the one that blocks on writing.

The master is in packet mode (TIOCPKT), so the server learns when a client flushes its
input (pyserial does so on every open, and on ``reset_input_buffer``): output still queued
here is then dropped too, as bytes sent to a port nobody read are lost on a real line, and
a new client never receives replies meant for a previous one. (One window remains: a client
opening within microseconds of the writer handing a chunk to a pty with room to spare may
get that chunk. Output only backs up when nobody reads, and then the pty is full and the
writer idle, so this does not arise when a dead client is replaced.)
"""

from __future__ import annotations

import errno
import fcntl
import logging
import os
import select
import struct
import termios
import threading
import tty
from collections.abc import Callable
from pathlib import Path

log = logging.getLogger(__name__)

CHUNK = 4096
MAX_PENDING = 256 * 1024  # bytes held for a client that does not read; then newest dropped
TIOCPKT_DATA = 0
TIOCPKT_FLUSHREAD = 1  # <asm-generic/termios.h>: the slave flushed its input queue


class PtyPort:
    """One pty in raw mode (bytes pass unchanged both ways), optionally named by a symlink."""

    def __init__(
        self,
        name: str,
        on_input: Callable[[bytes], None],
        link: Path | None = None,
        max_pending: int = MAX_PENDING,
    ) -> None:
        if link is not None and link.exists() and not link.is_symlink():
            raise FileExistsError(f"{link} exists and is not a symlink: not replacing it")
        self.name = name
        self.on_input = on_input
        self.max_pending = max_pending
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo, no line translation, 8 bits: the bytes as sent
        self.device = os.ttyname(self._slave)
        os.set_blocking(self.master, False)
        fcntl.ioctl(self.master, termios.TIOCPKT, struct.pack("i", 1))
        self.link = link
        if link is not None:
            tmp = link.with_name(f".{link.name}.tmp")
            tmp.unlink(missing_ok=True)
            tmp.symlink_to(self.device)
            os.replace(tmp, link)  # atomic: a stale link from a dead server is overwritten
        self.dropped = 0  # bytes dropped because nobody read them
        self.stalled = False  # the pty is full: output waits for the client to read
        self._pending = bytearray()
        self._cond = threading.Condition()
        self._closed = False
        self._wake_r, self._wake_w = os.pipe()
        self._reader = threading.Thread(target=self._read_loop, name=f"pty-rd-{name}", daemon=True)
        self._writer = threading.Thread(target=self._write_loop, name=f"pty-wr-{name}", daemon=True)

    @property
    def address(self) -> str:
        """What a client opens: the symlink if there is one, else the slave device."""
        return str(self.link) if self.link is not None else self.device

    def start(self) -> None:
        self._reader.start()
        self._writer.start()

    # ----- output (any thread) -----
    def write(self, data: bytes) -> None:
        """Queue bytes for the client; never blocks (bytes beyond ``max_pending`` are dropped)."""
        with self._cond:
            if self._closed:
                return
            room = self.max_pending - len(self._pending)
            if len(data) > room:
                if self.dropped == 0:
                    log.warning("%s: client not reading, dropping output", self.name)
                self.dropped += len(data) - max(room, 0)
                data = data[: max(room, 0)]
            if data:
                self._pending.extend(data)
                self._cond.notify()

    def discard_output(self) -> None:
        """Drop output not yet handed to the pty (a client flush drops what the pty holds)."""
        with self._cond:
            self._pending.clear()

    def _read_packet(self) -> bytes | None:
        """Reader thread, lock held: one read from the master; act on a flush, return data."""
        try:
            packet = os.read(self.master, CHUNK + 1)
        except BlockingIOError:
            return None
        if not packet:
            return None
        if packet[0] != TIOCPKT_DATA:  # a status byte alone (it comes before any later data)
            if packet[0] & TIOCPKT_FLUSHREAD:
                self._pending.clear()
            return None
        return packet[1:]

    def _write_loop(self) -> None:
        ready = select.poll()
        ready.register(self.master, select.POLLOUT)
        status = select.poll()  # POLLPRI: a packet-mode status (a client flush) not yet read
        status.register(self.master, select.POLLPRI)
        while True:
            with self._cond:
                while not self._pending and not self._closed:
                    self._cond.wait()
                if self._closed:
                    return
                if status.poll(0):
                    # the client flushed: the reader drops what is queued before we write on
                    self._cond.wait(0.001)
                    continue
                try:
                    # under the lock, so a discard cannot interleave with a write
                    n = os.write(self.master, self._pending[:CHUNK])
                except BlockingIOError:
                    n = 0
                except OSError as e:
                    log.error("%s: write to pty failed: %s", self.name, e)
                    return
                del self._pending[:n]
                self.stalled = n == 0
            if n == 0:
                ready.poll(100)  # pty buffer full: wait for the client to read

    # ----- input (reader thread) -----
    def _read_loop(self) -> None:
        poll = select.poll()
        poll.register(self.master, select.POLLIN)
        poll.register(self._wake_r, select.POLLIN)
        while True:
            events = poll.poll()
            if any(fd == self._wake_r for fd, _ in events):
                return
            try:
                with self._cond:  # a status byte is read and acted on atomically (see writer)
                    data = self._read_packet()
            except OSError as e:
                if e.errno == errno.EIO:  # cannot happen while we hold the slave; be explicit
                    log.error("%s: pty hung up", self.name)
                else:
                    log.error("%s: read from pty failed: %s", self.name, e)
                return
            if data:
                try:
                    self.on_input(data)
                except Exception:
                    log.exception("%s: input handler failed", self.name)

    # ----- teardown -----
    def close(self) -> None:
        """Stop the threads, close the pty and remove the symlink if it is still ours."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            self._cond.notify_all()
        os.write(self._wake_w, b"x")
        for t in (self._reader, self._writer):
            if t.is_alive():
                t.join(2.0)
        if self.link is not None:
            try:
                if os.readlink(self.link) == self.device:
                    self.link.unlink()
            except OSError:
                pass
        for fd in (self.master, self._slave, self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass
