"""Real-time performance of a served rack: lateness of replies and IEU frames at speed 1.

Starts ``station serve`` as its own process at speed 1 and measures, from a client
process as any rehearsal would see it:

* instrument replies: ``*IDN?`` to the oscillator over its pty, N times; lateness is the
  arrival time minus (send time + the instrument's configured reply latency);
* IEU frames over socketcand: sampling every ``period`` S2^T pulses for some seconds;
  lateness is the arrival time minus the frame's simulated time mapped to the wall by
  the server's session (speed and monotonic time origin, one machine's CLOCK_MONOTONIC).

Prints median, 99th percentile and maximum in milliseconds (target: p99 under 2 ms) and
the server's own slip line. ``python bench/hil_latency.py [queries] [seconds] [period]``.

``python bench/hil_latency.py --flood KIND[,KIND...] [queries]`` serves the whole ISU rack
and measures one quiet link (``*IDN?`` to the oscillator and ``STAT?`` to the table,
alternately) while other processes flood other links with the worst traffic a host can
send (:data:`FLOODS`; ``all`` runs every kind at once, ``none`` measures the quiet link
alone). Each flood finds the most demanding setting its instrument still accepts. The
quiet link's p99 lateness should stay within 2 ms; the server's slip is printed too.
"""

from __future__ import annotations

import argparse
import math
import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import serial

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # measure this tree, not whichever copy is installed

from instruments.isu.ieu import SERVED_MIN_PERIOD  # noqa: E402
from station.config.isu import load_config  # noqa: E402
from station.drivers.isu import IeuDriver, OscillatorDriver  # noqa: E402
from station.hil import link_map  # noqa: E402
from station.hil.profile import served  # noqa: E402

# flood kind -> what it sends (the flooding process reads and drops every reply)
FLOODS = {
    "preset": "counter1 gated by the 1 MHz S1^T line at the smallest PRESET it accepts, "
              "print and continue, its readings fetched with a stream of READ?",
    "ieu": "IEU sampling at the smallest PeriodTicks it accepts, over socketcand",
    "read": "counter2 in standby sent READ? as fast as the link takes it",
    "garbage": "counter3 sent random lines (printable, binary, over-long) as fast as it takes",
    "can": "socketcand sent STATUS requests and junk messages as fast as TCP takes them",
    "slcan": "the slcan pty sent frames, junk and over-long lines as fast as it takes them",
}
FLOOD_START_S = 1.0  # wall seconds the floods run before the quiet link is measured
TRIES = (1, 2, 5, 10, 15, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10_000, 20_000, 50_000,
         100_000, 200_000, 500_000, 1_000_000)


def _percentile(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, int(round(q * (len(s) - 1))))]


def _report(what: str, late_s: list[float]) -> None:
    ms = [x * 1e3 for x in late_s]
    print(f"{what:<28} n={len(ms):>6}  median {statistics.median(ms):6.3f} ms  "
          f"p99 {_percentile(ms, 0.99):6.3f} ms  max {max(ms):7.3f} ms", flush=True)


def replies(url: str, n: int, latency_s: float) -> list[float]:
    osc = OscillatorDriver("oscillator", url, timeout=2.0)
    try:
        osc.identify()  # first exchange opens the path
        out = []
        for _ in range(n):
            t0 = time.monotonic()
            osc.identify()
            out.append(time.monotonic() - t0 - latency_s)
        return out
    finally:
        osc.close()


def quiet_replies(urls: list[str], n: int, latency_s: float) -> list[float]:
    """Lateness of ``*IDN?``/``STAT?`` exchanges, alternating over ``urls`` (raw pyserial)."""
    ports = [serial.serial_for_url(u, timeout=5.0) for u in urls]
    try:
        for p in ports:
            p.write(b"*IDN?\n")
            p.read_until(b"\n")
        out = []
        for i in range(n):
            p = ports[i % len(ports)]
            cmd = b"*IDN?\n" if i % 2 == 0 else b"STAT?\n"
            t0 = time.monotonic()
            p.write(cmd)
            line = p.read_until(b"\n")
            t1 = time.monotonic()
            if not line.endswith(b"\n") or line.startswith(b"ERR"):
                raise SystemExit(f"quiet link: {cmd!r} answered {line!r}")
            out.append(t1 - t0 - latency_s)
        return out
    finally:
        for p in ports:
            p.close()


def frames(links: Path, seconds: float, period: int) -> list[float]:
    link = served(links)
    s = link.session
    ieu = IeuDriver("ieu", link.can["ieu"], timeout=2.0)
    out = []
    try:
        ieu.start(period)
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            m = ieu.bus.recv(1.0)
            now = time.monotonic()
            if m is None:
                continue
            out.append(now - (s.t0_monotonic + m.timestamp / s.speed))
        ieu.stop()
    finally:
        ieu.close()
    return out


# ----- floods (each runs in a process of its own: `--flooder KIND LINKS`) -----
def _drain(port: serial.Serial, stop: threading.Event, got: list[int]) -> threading.Thread:
    """Read and drop everything ``port`` receives until ``stop``; count bytes in ``got``."""
    def run() -> None:
        while not stop.is_set():
            try:
                got[0] += len(port.read(4096))
            except (serial.SerialException, OSError, TypeError):
                return
    t = threading.Thread(target=run, daemon=True)
    t.start()
    return t


def _ask(port: serial.Serial, cmd: str) -> str:
    port.reset_input_buffer()
    port.write(cmd.encode() + b"\n")
    return port.read_until(b"\n").decode("ascii", "replace").strip()


def _ready() -> None:
    """Tell the measuring process this flood is under way (one line on stdout)."""
    print("flooding", flush=True)


def _pump(port: serial.Serial, chunks: list[bytes], stop: threading.Event) -> int:
    """Write ``chunks`` round and round, 256 bytes at a time, until ``stop``; bytes written
    (a piece cut short by the write timeout is not counted)."""
    _ready()
    data = b"".join(chunks)
    pieces = [data[i:i + 256] for i in range(0, len(data), 256)]
    sent = 0
    i = 0
    while not stop.is_set():
        try:
            sent += port.write(pieces[i % len(pieces)]) or 0
        except serial.SerialTimeoutException:
            continue
        except (serial.SerialException, OSError):
            break
        i += 1
    return sent


def _serial_flood(url: str, chunks: list[bytes], stop: threading.Event,
                  setup: list[str] = ()) -> str:
    port = serial.serial_for_url(url, timeout=2.0, write_timeout=0.5)
    for cmd in setup:
        _ask(port, cmd)
    port.timeout = 0.2
    got = [0]
    reader = _drain(port, stop, got)
    sent = _pump(port, chunks, stop)
    reader.join(2.0)
    port.close()
    return f"sent {sent} B, received {got[0]} B"


def _garbage(rng: random.Random) -> list[bytes]:
    out = []
    for _ in range(64):
        kind = rng.randrange(3)
        if kind == 0:
            out.append(bytes(rng.randrange(32, 127) for _ in range(rng.randrange(1, 40))) + b"\n")
        elif kind == 1:
            out.append(bytes(rng.randrange(256) for _ in range(rng.randrange(1, 40))) + b"\n")
        else:
            out.append(b"X" * rng.randrange(257, 2000) + b"\n")
    return [b"".join(out)]


def flooder(kind: str, links: Path, stop: threading.Event, least: int) -> None:
    """Flood one link of the rack under ``links`` with ``kind`` traffic until ``stop``;
    ``least``: the smallest PRESET or PeriodTicks to try (preset, ieu)."""
    link = served(links)
    rng = random.Random(kind)
    if kind == "preset":
        panel = serial.serial_for_url(link.serial["patch_panel"], timeout=2.0)
        for cmd in ("CONN OSC1 C1 Z", "CONN OSC2 C1 X"):
            _ask(panel, cmd)
        panel.close()
        c1 = serial.serial_for_url(link.serial["counter1"], timeout=2.0, write_timeout=0.5)
        _ask(c1, "*RST")
        _ask(c1, "MODE Z")
        preset = None
        for v in (p for p in TRIES if p >= least):  # a counter may refuse at PRESET or OPER
            _ask(c1, "STBY")
            if _ask(c1, f"PRESET {v}") == "OK" and _ask(c1, "OPER") == "OK":
                preset = v
                break
        c1.close()
        if preset is None:
            raise SystemExit("flood preset: no PRESET accepted with OPER")
        what = _serial_flood(link.serial["counter1"], [b"READ?\n" * 64], stop)
        print(f"flood preset: PRESET {preset} on 1 MHz accepted in OPER; {what}", flush=True)
    elif kind == "ieu":
        ieu = IeuDriver("ieu", link.can["ieu"], timeout=2.0)
        accepted = None
        for period in (p for p in TRIES if p >= least):
            try:
                ieu.start(period)
            except Exception as e:  # noqa: BLE001 - refused: try a longer period
                print(f"flood ieu: PeriodTicks {period}: {e}", file=sys.stderr, flush=True)
                continue
            accepted = period
            break
        n = 0
        _ready()
        while not stop.is_set():
            if ieu.bus.recv(0.2) is not None:
                n += 1
        ieu.close()
        print(f"flood ieu: PeriodTicks {accepted} accepted; {n} frames received", flush=True)
    elif kind == "read":
        what = _serial_flood(link.serial["counter2"], [b"READ?\n" * 64], stop, ["STBY"])
        print(f"flood read: {what}", flush=True)
    elif kind == "garbage":
        what = _serial_flood(link.serial["counter3"], _garbage(rng), stop)
        print(f"flood garbage: {what}", flush=True)
    elif kind == "can":
        import socket

        cfg = link.can["ieu"]
        sock = socket.create_connection((cfg["host"], cfg["port"]))
        sock.recv(64)
        sock.sendall(b"< open ieu >")
        sock.recv(64)
        sock.sendall(b"< rawmode >")
        sock.recv(64)
        junk = (b"< send 080 8 03 01 00 00 00 00 00 00 >< send 7FF 1 00 >< bogus >"
                b"< send 080 9 1 2 3 4 5 6 7 8 9 >" + b"<" + b"x" * 900 + b">")
        got = [0]

        def drain() -> None:
            while not stop.is_set():
                try:
                    got[0] += len(sock.recv(65536))
                except OSError:
                    return
        threading.Thread(target=drain, daemon=True).start()
        sent = 0
        _ready()
        sock.settimeout(0.5)
        while not stop.is_set():
            try:
                sock.sendall(junk * 16)
            except TimeoutError:
                continue  # the server takes it at the bus's pace
            except OSError:
                break
            sent += len(junk) * 16
        sock.close()
        print(f"flood can: sent {sent} B, received {got[0]} B", flush=True)
    elif kind == "slcan":
        url = str(links / "ieu-slcan")
        junk = b"O\rt0808030100000000000000\rV\r" + b"x" * 100 + b"V\r" + b"tZZZ9\r"
        what = _serial_flood(url, [junk * 32], stop)
        print(f"flood slcan: {what}", flush=True)
    else:
        raise SystemExit(f"unknown flood {kind!r}: {', '.join(FLOODS)}")


def _loadavg() -> str:
    try:
        return Path("/proc/loadavg").read_text().split()[0]
    except OSError:
        return "?"


def _cpu_s(pid: int) -> float:
    """CPU seconds (user + system) a process has used so far (Linux /proc)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return math.nan
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _ordinary(nice: int) -> None:
    """In a flood process: ordinary scheduling, whatever the bench runs under (chrt, nice),
    so the floods compete as any other host program would."""
    if os.sched_getscheduler(0) != os.SCHED_OTHER:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    if nice:
        os.nice(-nice)


def _nice(pid: int) -> str:
    try:
        return str(os.getpriority(os.PRIO_PROCESS, pid))
    except OSError:
        return "?"


def _start_server(d: Path, only: str | None, nice: int = 0) -> tuple[Path, subprocess.Popen,
                                                                     Path]:
    links = d / "links"
    out = d / "server.out"
    cmd = [sys.executable, "-m", "laboratory.cli", "serve", "--speed", "1", "--links", str(links)]
    if only:
        cmd += ["--only", only]
    with open(out, "w") as log:
        server = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT,
                                  preexec_fn=(lambda: os.nice(nice)) if nice else None)
    while not (links / link_map.FILENAME).exists():
        if server.poll() is not None:
            raise SystemExit(f"server exited: {out.read_text()}")
        time.sleep(0.05)
    return links, server, out


def _stop_server(server: subprocess.Popen, out: Path) -> None:
    server.send_signal(signal.SIGTERM)
    server.wait(30)
    lines = out.read_text().strip().splitlines()
    for line in lines[-3:-1]:
        if line.startswith(("input held back", "garbage collections")):
            print("server:", line)
    print("server:", lines[-1] if lines else "(no output)", flush=True)


def flood_case(kinds: list[str], n: int, least: dict[str, int] | None = None,
               nice: int = 0) -> None:
    latency_s = load_config().instruments.serial.latency_s
    with tempfile.TemporaryDirectory() as d:
        links, server, out = _start_server(Path(d), None, nice)
        if nice:
            os.nice(nice)  # this (measuring) process too; the floods keep the default
        procs: list[subprocess.Popen] = []
        try:
            link = served(links)
            for k in kinds:  # each runs until told to stop (SIGTERM), then reports
                procs.append(subprocess.Popen(
                    [sys.executable, __file__, "--flooder", k, str(links),
                     str((least or {}).get(k, 1))], stdout=subprocess.PIPE, text=True,
                    preexec_fn=lambda: _ordinary(nice)))
            for k, p in zip(kinds, procs, strict=True):
                line = p.stdout.readline() if p.stdout else ""
                if line.strip() != "flooding":
                    raise SystemExit(f"flood {k} did not start: {line.strip()!r}")
            time.sleep(FLOOD_START_S)
            print(f"speed 1, reply latency {latency_s * 1e3:g} ms configured; floods: "
                  f"{', '.join(kinds) or 'none'}; load average {_loadavg()} before; server "
                  f"nice {_nice(server.pid)}", flush=True)
            cpu0, wall0 = _cpu_s(server.pid), time.monotonic()
            t0_before = served(links).session.t0_monotonic
            late = quiet_replies([link.serial["oscillator"], link.serial["table"]], n, latency_s)
            cpu = (_cpu_s(server.pid) - cpu0) / (time.monotonic() - wall0)
            slip = served(links).session.t0_monotonic - t0_before  # re-published on a slip
            _report("quiet link (*IDN?/STAT?)", late)
            print(f"server CPU meanwhile: {cpu:.0%} of one core; slip meanwhile {slip:.3f} s",
                  flush=True)
            print(f"load average {_loadavg()} after", flush=True)
        finally:
            for p in procs:
                p.send_signal(signal.SIGTERM)
            for p in procs:
                try:
                    out_text, _ = p.communicate(timeout=30)
                except subprocess.TimeoutExpired:
                    p.kill()
                    out_text, _ = p.communicate()
                print(out_text.strip(), flush=True)
            _stop_server(server, out)


def main(argv: list[str]) -> None:
    if argv[:1] == ["--flooder"]:
        stop = threading.Event()
        signal.signal(signal.SIGTERM, lambda *_: stop.set())
        flooder(argv[1], Path(argv[2]), stop, int(argv[3]))
        os._exit(0)  # daemon readers may still be blocked in a read
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("queries", nargs="?", type=int, default=2000,
                   help="*IDN? queries to the oscillator (default 2000)")
    p.add_argument("seconds", nargs="?", type=float, default=10.0,
                   help="seconds of IEU frames (default 10)")
    p.add_argument("period", nargs="?", type=int, default=SERVED_MIN_PERIOD,
                   help=f"S2^T pulses (default {SERVED_MIN_PERIOD}, 20 ms: the least a served "
                   "IEU accepts)")
    p.add_argument("--flood", help=f"comma-separated: {', '.join(FLOODS)}, all or none")
    p.add_argument("--nice", type=int, default=0, help="niceness increment of the server and "
                   "of the measuring process (negative: ahead of other work on a busy machine; "
                   "needs the privilege)")
    p.add_argument("--least-preset", type=int, default=1, help="smallest counter PRESET "
                   "the preset flood tries (default 1: whatever the counter accepts)")
    p.add_argument("--least-period", type=int, default=1, help="smallest IEU PeriodTicks "
                   "the ieu flood tries (default 1: whatever the IEU accepts)")
    a = p.parse_args(argv)
    if a.flood is not None:
        kinds = list(FLOODS) if a.flood == "all" else \
            [k for k in a.flood.split(",") if k and k != "none"]
        for k in kinds:
            if k not in FLOODS:
                p.error(f"unknown flood {k!r}: {', '.join(FLOODS)}")
        flood_case(kinds, a.queries, {"preset": a.least_preset, "ieu": a.least_period},
                   a.nice)
        return
    latency_s = load_config().instruments.serial.latency_s
    with tempfile.TemporaryDirectory() as d:
        links, server, out = _start_server(Path(d), "oscillator,ieu")
        try:
            url = served(links).serial["oscillator"]
            print(f"speed 1, reply latency {latency_s * 1e3:g} ms configured; IEU period "
                  f"{a.period} S2^T pulses")
            _report("reply lateness (*IDN?)", replies(url, a.queries, latency_s))
            _report("IEU frame lateness", frames(links, a.seconds, a.period))
        finally:
            _stop_server(server, out)


if __name__ == "__main__":
    main(sys.argv[1:])
