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

Input is admitted at the link's line rate (``admit``, a :class:`TokenBucket`): the reader
takes bytes from the pty only as fast as the line would carry them and in bounded slices,
and not at all while ``ready()`` says the consumer is behind; a host writing faster fills
the pty and then blocks, as on a real serial port. The symlink is made in the directory
without following symlinks (:class:`DirHandle`).
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
import time
import tty
from collections.abc import Callable
from pathlib import Path

from station.hil.links_dir import DirHandle
from station.hil.throttle import TokenBucket

log = logging.getLogger(__name__)

CHUNK = 4096
MAX_PENDING = 64 * 1024  # bytes held for a client that does not read; then newest dropped
LEAST_READ = 32  # bytes: an admitted read waits for at least this much line time
BUSY_WAIT_S = 0.002  # the consumer is behind: look again this much later
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
        admit: TokenBucket | None = None,
        slice_bytes: int = CHUNK,
        ready: Callable[[], bool] | None = None,
        directory: DirHandle | None = None,
    ) -> None:
        self.name = name
        self.on_input = on_input
        self.max_pending = max_pending
        self.admit = admit
        self.slice = max(1, min(slice_bytes, CHUNK))
        self.ready = ready
        self.link = link
        self._dir: DirHandle | None = None
        self._own_dir = False
        if link is not None:
            if directory is None:
                directory, self._own_dir = DirHandle(link.parent), True
            elif directory.path != link.parent.resolve():
                raise ValueError(f"{link} is not in {directory.path}")
            self._dir = directory
        self.master, self._slave = os.openpty()
        try:
            tty.setraw(self._slave)  # no echo, no line translation, 8 bits: the bytes as sent
            self.device = os.ttyname(self._slave)
            os.set_blocking(self.master, False)
            fcntl.ioctl(self.master, termios.TIOCPKT, struct.pack("i", 1))
            if self._dir is not None and link is not None:
                # atomic and never through a symlink: a stale link from a dead server is
                # replaced, a file of that name is refused
                self._dir.symlink(link.name, self.device)
        except BaseException:
            self._close_fds((self.master, self._slave))
            if self._own_dir and self._dir is not None:
                self._dir.close()
            raise
        self.dropped = 0  # bytes dropped because nobody read them
        self.held = 0  # times the reader left input in the pty (line busy, consumer behind)
        self.stalled = False  # the pty is full: output waits for the client to read
        self._pending = bytearray()
        self._cond = threading.Condition()
        self._flushed = select.poll()  # write(), lock held: a client flush not yet acted on
        self._flushed.register(self.master, select.POLLPRI)
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
        """Send bytes to the client: straight to the pty if nothing is queued and it has
        room, else queued for the writer thread. Never blocks; bytes beyond ``max_pending``
        are dropped."""
        with self._cond:
            if self._closed:
                return
            room = self.max_pending - len(self._pending)
            if len(data) > room:
                if self.dropped == 0:
                    log.warning("%s: client not reading, dropping output", self.name)
                self.dropped += len(data) - max(room, 0)
                data = data[: max(room, 0)]
            if data and not self._pending and not self._flushed.poll(0):
                # nothing queued: hand it to the pty now, without waking the writer thread
                try:
                    n = os.write(self.master, data[:CHUNK])
                except OSError:  # full (or failing: the writer thread reports that)
                    n = 0
                data = data[n:]
            if data:
                self._pending.extend(data)
                self._cond.notify()

    def discard_output(self) -> None:
        """Drop output not yet handed to the pty (a client flush drops what the pty holds)."""
        with self._cond:
            self._pending.clear()

    def _read_packet(self, n: int) -> bytes | None:
        """Reader thread, lock held: one read (up to ``n`` bytes) from the master; act on a
        flush, return data."""
        try:
            packet = os.read(self.master, n + 1)
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
    def _allowance(self) -> tuple[int, float]:
        """Reader thread: (bytes the link admits now, seconds to wait if none)."""
        if self.ready is not None and not self.ready():
            return 0, BUSY_WAIT_S
        if self.admit is None:
            return self.slice, 0.0
        now = time.monotonic()
        need = min(LEAST_READ, self.slice)
        wait = self.admit.wait_s(need, now)
        if wait > 0:
            return 0, wait
        return min(self.slice, int(self.admit.available(now))), 0.0

    def _read_loop(self) -> None:
        data_or_wake = select.poll()
        data_or_wake.register(self.master, select.POLLIN)
        data_or_wake.register(self._wake_r, select.POLLIN)
        wake_only = select.poll()
        wake_only.register(self._wake_r, select.POLLIN)
        while True:
            n, wait = self._allowance()
            if n == 0:  # the line is busy: leave the host's bytes in the pty meanwhile
                self.held += 1
                if wake_only.poll(max(1, round(min(wait, 1.0) * 1000))):
                    return
                continue
            events = data_or_wake.poll()
            if any(fd == self._wake_r for fd, _ in events):
                return
            try:
                with self._cond:  # a status byte is read and acted on atomically (see writer)
                    data = self._read_packet(n)
            except OSError as e:
                if e.errno == errno.EIO:  # cannot happen while we hold the slave; be explicit
                    log.error("%s: pty hung up", self.name)
                else:
                    log.error("%s: read from pty failed: %s", self.name, e)
                return
            if data:
                if self.admit is not None:
                    self.admit.take(len(data), time.monotonic())
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
        if self._dir is not None and self.link is not None:
            self._dir.unlink(self.link.name, if_target=self.device)
            if self._own_dir:
                self._dir.close()
        self._close_fds((self.master, self._slave, self._wake_r, self._wake_w))

    @staticmethod
    def _close_fds(fds: tuple[int, ...]) -> None:
        for fd in fds:
            try:
                os.close(fd)
            except OSError:
                pass
