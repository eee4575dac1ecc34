"""Real-time performance of a served rack: lateness of replies and IEU frames at speed 1.

Starts ``station.hil.server`` as its own process at speed 1 and measures, from a client
process as any rehearsal would see it:

* instrument replies: ``*IDN?`` to the oscillator over its pty, N times; lateness is the
  arrival time minus (send time + the instrument's configured reply latency);
* IEU frames over socketcand: sampling every ``period`` S2^T pulses for some seconds;
  lateness is the arrival time minus the frame's simulated time mapped to the wall by
  the server's session (speed and monotonic time origin, one machine's CLOCK_MONOTONIC).

Prints median, 99th percentile and maximum in milliseconds (target: p99 under 2 ms) and
the server's own slip line. ``python bench/hil_latency.py [queries] [seconds] [period]``.
"""

from __future__ import annotations

import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from station.config import load_config
from station.drivers import IeuDriver, OscillatorDriver
from station.hil import link_map
from station.hil.profile import served


def _percentile(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, int(round(q * (len(s) - 1))))]


def _report(what: str, late_s: list[float]) -> None:
    ms = [x * 1e3 for x in late_s]
    print(f"{what:<28} n={len(ms):>6}  median {statistics.median(ms):6.3f} ms  "
          f"p99 {_percentile(ms, 0.99):6.3f} ms  max {max(ms):7.3f} ms")


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


def frames(links: Path, seconds: float, period: int) -> list[float]:
    link = served(links)
    s = link.session
    ieu = IeuDriver(link.can["ieu"], timeout=2.0)
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


def main(argv: list[str]) -> None:
    n = int(argv[0]) if argv else 2000
    seconds = float(argv[1]) if len(argv) > 1 else 10.0
    period = int(argv[2]) if len(argv) > 2 else 100  # S2^T pulses: 10 ms
    latency_s = load_config().instruments.serial.latency_s
    with tempfile.TemporaryDirectory() as d:
        links = Path(d) / "links"
        log = open(Path(d) / "server.out", "w")
        server = subprocess.Popen(
            [sys.executable, "-m", "station.hil.server", "--speed", "1", "--links", str(links),
             "--only", "oscillator,ieu"], stdout=log, stderr=subprocess.STDOUT)
        try:
            while not (links / link_map.FILENAME).exists():
                if server.poll() is not None:
                    raise SystemExit(f"server exited: {(Path(d) / 'server.out').read_text()}")
                time.sleep(0.05)
            url = served(links).serial["oscillator"]
            print(f"speed 1, reply latency {latency_s * 1e3:g} ms configured; IEU period "
                  f"{period} S2^T pulses")
            _report("reply lateness (*IDN?)", replies(url, n, latency_s))
            _report("IEU frame lateness", frames(links, seconds, period))
        finally:
            server.send_signal(signal.SIGTERM)
            server.wait(15)
            log.close()
        print((Path(d) / "server.out").read_text().strip().splitlines()[-1])


if __name__ == "__main__":
    main(sys.argv[1:])
