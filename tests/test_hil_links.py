"""The real-time OS-level links: the same drivers talk to a rack served by another process.

A server process (``station serve``) runs the simulated rack in real time
(times 20) and serves the table on a pty and the IEU on socketcand and on slcan; this
process reaches them only through pyserial and python-can, exactly as it would reach
hardware. No assertion depends on wall-clock timing.
"""

from __future__ import annotations

import math
import os
import threading
import time
from pathlib import Path

import can
import pytest
import serial
from hil_helpers import serving

from station.clock import WallClock
from station.drivers.isu import IeuDriver, TableDriver
from station.hil import link_map
from station.hil.pty_port import PtyPort

SPEED = 20.0
PERIOD = 1000  # S2^T pulses: 0.1 s of simulated time
STRING_HZ = 20000.0


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """A running server; yields (links dir, entries, process). Stops and checks the cleanup."""
    args = ["--seed", "7", "--speed", str(SPEED), "--only", "table,ieu"]
    with serving(tmp_path_factory.mktemp("hil"), args) as s:
        yield s


def _address(entries, instrument: str, kind: str, scheme: str | None = None) -> str:
    for e in entries:
        if e.instrument == instrument and e.kind == kind:
            is_socketcand = e.address.startswith("socketcand://")
            if scheme is None or (scheme == "socketcand") == is_socketcand:
                return e.address
    raise AssertionError(f"no {kind} link for {instrument} in {entries}")


def test_link_map(served):
    links, entries, _ = served
    kinds = sorted((e.instrument, e.kind) for e in entries)
    assert kinds == [("ieu", "can"), ("ieu", "can"), ("table", "serial")]
    table = Path(_address(entries, "table", "serial"))
    assert table == links / "table" and os.readlink(table).startswith("/dev/pts/")
    cfg = link_map.can_config(_address(entries, "ieu", "can", "socketcand"))
    assert cfg["interface"] == "socketcand" and cfg["host"] == "127.0.0.1" and cfg["port"] > 0


def test_table_over_pty(served):
    _, entries, _ = served
    table = TableDriver("table", _address(entries, "table", "serial"), WallClock(), timeout=10.0)
    try:
        assert table.identify().startswith("ISU-LAB,TT-4AX")
        target = 37.25
        table.move(3, target)
        table.wait_still(timeout=60.0, poll=0.1)
        err_arcsec = abs(table.position(3) - target) * 3600.0
        assert err_arcsec < 2.0
        table.move(3, 0.0)
    finally:
        table.close()


def _check_samples(ieu: IeuDriver, n: int = 6) -> None:
    ieu.start(PERIOD)
    try:
        samples = [ieu.next_sample(timeout=10.0) for _ in range(n)]
    finally:
        ieu.stop()
    for a, b in zip(samples, samples[1:], strict=False):
        assert b.seq == (a.seq + 1) % 65536
    expect = STRING_HZ * PERIOD * 1e-4  # S2^T is 10 kHz
    for s in samples:
        assert s.timer == PERIOD
        assert s.flags == 0
        for count in s.accel:
            assert math.isclose(count, expect, rel_tol=0.10), s


@pytest.mark.parametrize("kind, extra", [("socketcand", {}), ("slcan", {"bitrate": 500000})])
def test_ieu_over_can_link(served, kind, extra):
    _, entries, _ = served
    cfg = link_map.can_config(_address(entries, "ieu", "can", kind)) | extra
    ieu = IeuDriver("ieu", cfg, timeout=10.0)
    try:
        assert ieu.identify().startswith("ISU-LAB,IEU")
        _check_samples(ieu)
    finally:
        ieu.close()


def test_sniffer_sees_commands_and_samples(served):
    """A second socketcand client sees the bus: the host's command and the IEU's frames."""
    _, entries, _ = served
    cfg = link_map.can_config(_address(entries, "ieu", "can", "socketcand"))
    sniffer = can.Bus(**cfg)
    ieu = IeuDriver("ieu", cfg, timeout=10.0)
    try:
        ieu.start(PERIOD)
        first = ieu.next_sample(timeout=10.0)
        ieu.stop()
        seen: list[can.Message] = []
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            m = sniffer.recv(0.5)
            if m is None:
                if seen:
                    break
                continue
            seen.append(m)
        ids = [m.arbitration_id for m in seen]
        assert 0x080 in ids  # the START command, sent by the other client
        assert 0x104 in ids  # a timer frame
        ts = [m.timestamp for m in seen]
        assert ts == sorted(ts) and first.t in ts  # simulated time, the same for both clients
    finally:
        ieu.close()
        sniffer.shutdown()


def test_pty_port_is_transparent_and_drops_stale_output(tmp_path):
    """Every byte value passes unchanged both ways; a new client never gets old output."""
    got = bytearray()
    arrived = threading.Event()

    def on_input(data: bytes) -> None:
        got.extend(data)
        if len(got) >= 1024:
            arrived.set()

    port = PtyPort("raw", on_input, tmp_path / "raw", max_pending=64 * 1024)
    port.start()
    try:
        every = bytes(range(256)) * 4
        with serial.serial_for_url(str(tmp_path / "raw"), timeout=10.0) as client:
            client.write(every)
            assert arrived.wait(10.0) and bytes(got) == every
            port.write(every)
            assert client.read(len(every)) == every
        for _ in range(100):  # nobody reads: far more than the pty and the queue hold
            port.write(b"y" * 4096)
        assert port.dropped > 0
        deadline = time.monotonic() + 10.0
        while not port.stalled and time.monotonic() < deadline:  # the pty is full
            time.sleep(0.01)
        assert port.stalled
        with serial.serial_for_url(str(tmp_path / "raw"), timeout=0.1) as client:
            before = b""
            for _ in range(100):  # the first markers may go with the flush; repeat until one lands
                port.write(b"fresh\n")
                before += client.read_until(b"fresh\n")
                if before.endswith(b"fresh\n"):
                    break
            assert before.endswith(b"fresh\n") and b"y" not in before
    finally:
        port.close()
    assert not (tmp_path / "raw").exists()


def test_slcan_over_long_line_is_refused_whole(served):
    """65 bytes then V, one line: one BEL and nothing executed; then N answers."""
    links, _, _ = served
    with serial.serial_for_url(str(links / "ieu-slcan"), timeout=10.0) as port:
        port.write(b"x" * 65 + b"V\r")
        port.write(b"N\r")
        got = port.read_until(b"NSIM1\r")
    assert got == b"\aNSIM1\r"


def _scd_read_until(sock, buf: bytearray, pred) -> str:
    """Read socketcand messages into ``buf`` until ``pred(message)``; return that message."""
    while True:
        text = buf.decode("ascii")
        end = text.find(">")
        if end >= 0:
            msg = text[: end + 1].strip()
            del buf[: end + 1]
            if pred(msg):
                return msg
            continue
        chunk = sock.recv(4096)
        assert chunk, "socketcand server closed the connection"
        buf.extend(chunk)


def test_socketcand_repeated_rawmode_delivers_each_frame_once(served):
    """rawmode sent three times: acknowledged each time; every IEU reply arrives once."""
    import socket

    import cantools

    import config

    _, entries, _ = served
    cfg = link_map.can_config(_address(entries, "ieu", "can", "socketcand"))
    cmd = cantools.database.load_file(str(config.path(config.IEU_DBC))) \
        .get_message_by_name("IEU_COMMAND")

    def send(command: int, period: int = 0) -> bytes:  # unused fields must be zero
        data = cmd.encode({"Command": command, "PeriodTicks": period, "Seq": 0})
        return f"< send {cmd.frame_id:03X} {len(data)} {' '.join(f'{b:X}' for b in data)} >" \
            .encode()

    buf = bytearray()
    with socket.create_connection((cfg["host"], cfg["port"]), timeout=10.0) as sock:
        assert _scd_read_until(sock, buf, lambda m: True) == "< hi >"
        sock.sendall(b"< open ieu >")
        assert _scd_read_until(sock, buf, lambda m: True) == "< ok >"
        sock.sendall(b"< rawmode >< rawmode >< rawmode >")
        for _ in range(3):
            assert _scd_read_until(sock, buf, lambda m: True) == "< ok >"
        sock.sendall(send(3))  # STATUS: the IEU answers with one IEU_STATUS frame, idle
        sock.sendall(send(1, 10_000))  # START: answered with IEU_STATUS, running
        statuses = []
        while not statuses or not statuses[-1].endswith(" >") or \
                statuses[-1].split()[4][:2] != "01":
            statuses.append(_scd_read_until(sock, buf, lambda m: m.startswith("< frame 081")))
        sock.sendall(send(0))  # STOP
    assert [s.split()[4][:2] for s in statuses] == ["00", "01"]  # State: idle, then running
