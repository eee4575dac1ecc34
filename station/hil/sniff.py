"""A bus monitor for a served (or real) IEU: plain python-can plus the shipped DBC.

``python -m station.hil.sniff --links DIR [--out FILE] [--seconds S]`` connects to the
socketcand link of the rack served under DIR as a second client (next to whatever
procedure is running), decodes every frame with config/ieu.dbc and writes one JSON line
per frame (``t``, ``id``, ``name``, ``signals``; ``error`` for a frame the DBC cannot
decode). It uses no station driver on purpose: it is what any laboratory tool would see.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from pathlib import Path

import can
import cantools

import config
from station.hil.profile import served


def decode(db: cantools.database.Database, m: can.Message) -> dict:
    rec = {"t": m.timestamp, "id": m.arbitration_id, "data": bytes(m.data).hex()}
    try:
        spec = db.get_message_by_frame_id(m.arbitration_id)
        rec["name"] = spec.name
        rec["signals"] = spec.decode(bytes(m.data), decode_choices=False)
    except (KeyError, ValueError, cantools.database.errors.DecodeError) as e:
        rec["error"] = str(e)
    return rec


def sniff(links_dir: Path, out, seconds: float | None, stop: threading.Event) -> int:
    """Decode frames until ``stop`` is set or ``seconds`` pass; returns the frame count."""
    cfg = served(links_dir).can["ieu"]
    db = cantools.database.load_file(str(config.path(config.IEU_DBC)))
    n = 0
    end = None if seconds is None else time.monotonic() + seconds
    with can.Bus(**cfg) as bus:
        while not stop.is_set() and (end is None or time.monotonic() < end):
            m = bus.recv(0.2)
            if m is None:
                continue
            out.write(json.dumps(decode(db, m)) + "\n")
            out.flush()
            n += 1
    return n


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m station.hil.sniff", description=__doc__)
    p.add_argument("--links", type=Path, required=True, help="directory of the served rack")
    p.add_argument("--out", type=Path, help="JSON Lines file (default: standard output)")
    p.add_argument("--seconds", type=float, help="stop after this many wall seconds")
    a = p.parse_args(argv)
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    try:
        if a.out is None:
            n = sniff(a.links, sys.stdout, a.seconds, stop)
        else:
            with open(a.out, "w", encoding="utf-8") as f:
                n = sniff(a.links, f, a.seconds, stop)
    except (FileNotFoundError, KeyError, OSError, can.CanError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"{n} frames", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
