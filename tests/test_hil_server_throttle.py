"""What one link may make the server do: line-rate admission, bounded slices and backlog,
rate-limited refusal logs, and input applied in arrival order.

The token-bucket arithmetic is checked with explicit times; the pty tests check counts of
bytes admitted (never how long anything took).
"""

from __future__ import annotations

import logging
import threading
import time

import pytest
import serial

from instruments.base import ByteInstrument
from station.hil import throttle
from station.hil.pty_port import PtyPort
from station.hil.realtime import RealtimeEnv
from station.hil.serial_link import MAX_BACKLOG, SerialPtyLink
from station.hil.throttle import LogLimiter, Rate, TokenBucket


def test_token_bucket_arithmetic():
    b = TokenBucket(rate=1000.0, burst=256.0, now=10.0)
    assert b.available(10.0) == 256.0  # starts full
    b.take(200, 10.0)
    assert b.available(10.0) == 56.0
    assert b.wait_s(64, 10.0) == pytest.approx(0.008)  # 8 more bytes at 1000 B/s
    assert b.available(10.1) == pytest.approx(156.0)
    assert b.available(11.0) == 256.0  # never more than the burst
    b.take(300, 11.0)  # a read may overdraw: the debt is paid by waiting
    assert b.available(11.0) == pytest.approx(-44.0)
    assert b.wait_s(1, 11.0) == pytest.approx(0.045)
    assert b.wait_s(10_000, 11.0) == pytest.approx(0.300)  # at most a full burst is awaited
    assert b.available(5.0) == pytest.approx(-44.0)  # time never runs backwards


def test_rates_of_the_links():
    s = throttle.SERIAL
    assert s.per_s == 11_520.0  # 115200 baud, 10 bits a byte
    assert s.wall_rate(1.0) == 11_520.0
    assert s.wall_rate(2.0) == 23_040.0  # the rack's time runs twice as fast
    assert s.wall_rate(500.0) == s.wall_cap  # the simulation thread's share of one link
    assert throttle.SOCKETCAND_FRAMES.wall_rate(1.0) == 2_000.0
    with pytest.raises(ValueError, match="positive rate"):
        TokenBucket.of(Rate(0.0, 1.0, 1.0, 1), 1.0, 0.0)


def test_log_limiter_counts_what_it_suppresses(caplog):
    lim = LogLimiter(logging.getLogger("test.limiter"), every_s=1.0)
    with caplog.at_level(logging.INFO, logger="test.limiter"):
        for i in range(100):
            lim.info(5.0 + i * 0.01, "refused %d", i)  # 100 refusals within a second
        lim.info(6.5, "refused %d", 100)
    assert [r.getMessage() for r in caplog.records] == [
        "refused 0", "refused 100 (and 99 more refused since the last report)"]


class Sink:
    """Collects what a PtyPort hands on, and each slice's size."""

    def __init__(self) -> None:
        self.data = bytearray()
        self.slices: list[int] = []
        self.cond = threading.Condition()

    def __call__(self, data: bytes) -> None:
        with self.cond:
            self.data += data
            self.slices.append(len(data))
            self.cond.notify_all()

    def wait_for(self, n: int, timeout: float = 10.0) -> bytes:
        with self.cond:
            self.cond.wait_for(lambda: len(self.data) >= n, timeout)
            return bytes(self.data)


def test_pty_admits_no_more_than_the_line_allows(tmp_path):
    """A bucket of 100 bytes that (practically) never refills: of a 1000-byte write, no
    more than 100 bytes get in (whole reads of 32: a read waits for that much line time),
    in order; the rest waits in the pty."""
    sink = Sink()
    bucket = TokenBucket(rate=1e-6, burst=100.0, now=0.0)  # starts full; never refills
    port = PtyPort("slow", sink, tmp_path / "slow", admit=bucket, slice_bytes=32)
    port.start()
    try:
        payload = bytes(range(250)) * 4
        with serial.serial_for_url(str(tmp_path / "slow"), timeout=10.0) as client:
            client.write(payload)
            sink.wait_for(69)  # reads go on while 32 bytes of the 100 are left
            time.sleep(0.2)  # room for any excess to show (there must be none)
            n = len(sink.data)
            assert 69 <= n <= 100 and bytes(sink.data) == payload[:n]
            assert max(sink.slices) <= 32
            assert port.held > 0  # counted for the server's closing report
    finally:
        port.close()


def test_pty_reads_nothing_while_the_consumer_is_behind(tmp_path):
    sink = Sink()
    ready = threading.Event()
    port = PtyPort("gated", sink, tmp_path / "gated", ready=ready.is_set)
    port.start()
    try:
        with serial.serial_for_url(str(tmp_path / "gated"), timeout=10.0) as client:
            client.write(b"*IDN?\n")
            time.sleep(0.2)
            assert sink.data == b""  # held in the pty, not read
            ready.set()
            assert sink.wait_for(6) == b"*IDN?\n"
    finally:
        port.close()


def test_serial_link_backlog_is_bounded(tmp_path):
    """With the simulation thread not running, a link posts at most MAX_BACKLOG bytes
    (plus the slice in flight) and leaves the rest of a flood with the host."""
    env = RealtimeEnv(speed=100.0)  # fast line: the bound, not the rate, stops it here
    inst = ByteInstrument("dummy", env, 0.002)
    link = SerialPtyLink(env, inst, tmp_path / "dummy")
    link.start()
    try:
        with serial.serial_for_url(str(tmp_path / "dummy"), timeout=10.0,
                                   write_timeout=10.0) as client:
            client.write(b"READ?\n" * 1000)  # 6000 bytes, written into the pty at once
            deadline = time.monotonic() + 10.0
            while link.posted < MAX_BACKLOG and time.monotonic() < deadline:
                time.sleep(0.01)
            time.sleep(0.2)
            assert MAX_BACKLOG <= link.posted <= MAX_BACKLOG + throttle.SERIAL.slice
            assert link.applied == 0
    finally:
        link.close()


def test_inputs_apply_in_arrival_order_after_a_slip():
    """The wall-to-tick mapping moves back when the physics slips; a later input must still
    apply after an earlier one (the bytes of one link stay in order)."""
    env = RealtimeEnv(speed=1.0)
    env.timeout(10 * 10**9)  # something far ahead: peek() is finite
    order: list[str] = []
    w = env.wall_at(env.now + 5_000_000)  # 5 ms into the run
    env._schedule((w, lambda: order.append("first"), None))
    env._wall0 += 1.0  # the physics slipped a second: later walls map to earlier ticks
    env._schedule((w + 0.0001, lambda: order.append("second"), None))
    env.run(until=env.now + 10**9)
    assert order == ["first", "second"]



class FakeHub:
    """What a SocketcandServer needs of the CAN hub."""

    class env:  # noqa: N801 - stands in for the environment's attribute
        speed = 1.0

    def attach(self, adapter) -> None:
        pass

    def detach(self, adapter) -> None:
        pass


def test_socketcand_serves_a_bounded_number_of_clients():
    import socket

    from station.hil.socketcand import MAX_CLIENTS, SocketcandServer

    server = SocketcandServer(FakeHub(), "ieu")  # type: ignore[arg-type]
    server.start()
    socks = []
    try:
        for _ in range(MAX_CLIENTS):
            s = socket.create_connection((server.host, server.port), timeout=10.0)
            socks.append(s)
            assert s.recv(64) == b"< hi >"
        extra = socket.create_connection((server.host, server.port), timeout=10.0)
        socks.append(extra)
        got = b""
        while chunk := extra.recv(64):
            got += chunk
        assert got == b"< error too many clients >"
        assert server.clients == MAX_CLIENTS
    finally:
        for s in socks:
            s.close()
        server.close()
