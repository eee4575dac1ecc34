"""A bus monitor for a served (or real) IEU: plain python-can plus the shipped DBC.

``python -m station.hil.sniff --links DIR [--out FILE] [--seconds S]`` connects to the
socketcand link of the rack served under DIR as a second client (next to whatever
procedure is running), decodes every frame with config/ieu.dbc and writes one JSON line
per frame (``t``, ``id``, ``name``, ``signals``; ``error`` for a frame the DBC cannot
decode). Frames that carry an end-to-end check get ``check``: ``ok`` or ``failed`` (the
CRC-8 of IEU_STATUS and IEU_ERROR; IEU_CHECK's CRC-32C over the sample's four count frames
seen before it, ``incomplete`` if some were not seen). It uses no station driver on
purpose: it is what any laboratory tool would see with the DBC and its comments.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from pathlib import Path
from typing import TextIO

import can
import cantools
from crccheck.crc import Crc8Autosar, Crc32C

import config
from station.hil.profile import served

COUNT_FRAMES = ("IEU_GYRO", "IEU_ACCEL_A", "IEU_ACCEL_B", "IEU_TIMER")
KEEP = 64  # sequence numbers whose count frames are kept for their IEU_CHECK


class Checker:
    """Verifies the IEU's end-to-end checks on the frames seen, in bus order."""

    def __init__(self) -> None:
        self.counts: dict[int, dict[str, bytes]] = {}

    def check(self, name: str, frame_id: int, data: bytes, sig: dict) -> str | None:
        if name in COUNT_FRAMES:
            self.counts.setdefault(int(sig["Seq"]), {})[name] = data
            while len(self.counts) > KEEP:
                del self.counts[next(iter(self.counts))]
            return None
        if name == "IEU_CHECK":
            got = self.counts.pop(int(sig["Seq"]), {})
            if len(got) < len(COUNT_FRAMES):
                return "incomplete"
            crc = Crc32C.calc(b"".join(got[n] for n in COUNT_FRAMES))
            return "ok" if crc == int(sig["Crc"]) else "failed"
        if "Crc" in sig:  # IEU_STATUS, IEU_ERROR: CRC-8 of the identifier and other bytes
            at = len(data) - 1
            crc = Crc8Autosar.calc(frame_id.to_bytes(2, "little") + data[:at])
            return "ok" if crc == data[at] else "failed"
        return None


def decode(db: cantools.database.can.Database, m: can.Message,
           checker: Checker | None = None) -> dict:
    data = bytes(m.data)
    rec = {"t": m.timestamp, "id": m.arbitration_id, "data": data.hex()}
    try:
        spec = db.get_message_by_frame_id(m.arbitration_id)
        rec["name"] = spec.name
        if len(data) != spec.length:
            raise ValueError(f"{len(data)} bytes, {spec.name} has {spec.length}")
        rec["signals"] = sig = spec.decode(data, decode_choices=False)
    except (KeyError, ValueError, cantools.database.errors.DecodeError) as e:
        rec["error"] = str(e)
        return rec
    if checker is not None:
        verdict = checker.check(spec.name, m.arbitration_id, data, dict(sig))
        if verdict is not None:
            rec["check"] = verdict
    return rec


def sniff(links_dir: Path, out: TextIO, seconds: float | None, stop: threading.Event) -> int:
    """Decode frames until ``stop`` is set or ``seconds`` pass; returns the frame count."""
    cfg = served(links_dir).can["ieu"]
    db = cantools.database.load_file(str(config.path(config.IEU_DBC)))
    assert isinstance(db, cantools.database.can.Database)
    checker = Checker()
    n = 0
    end = None if seconds is None else time.monotonic() + seconds
    with can.Bus(**cfg) as bus:
        while not stop.is_set() and (end is None or time.monotonic() < end):
            m = bus.recv(0.2)
            if m is None:
                continue
            out.write(json.dumps(decode(db, m, checker)) + "\n")
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
