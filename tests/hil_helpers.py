"""Starting and stopping a rack server (``station serve``) for a test module.

``serving(base, args)`` starts the server as a subprocess with stdout/stderr to
``base/server.out``/``server.err`` and links under ``base/links``, waits for its
``links.json`` (its readiness signal), yields ``(links dir, entries, process)``, then stops
it with SIGTERM and checks that it exited 0, removed everything it published and printed
its closing line.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from station.hil import link_map

START_DEADLINE_S = 20.0


def stop(proc: subprocess.Popen) -> int:
    """SIGTERM, then SIGKILL if it does not go; the process is always reaped."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(10.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10.0)
    return proc.returncode


def text(path: Path) -> str:
    """The tail of a server output file (of both, given the directory)."""
    if path.is_dir():
        return " | ".join(text(p) for p in sorted(path.glob("server.*")))
    return path.read_text()[-2000:]


def slipped_s(base: Path) -> float | None:
    """Seconds the stopped server reported it slipped behind real time (None if not yet)."""
    m = re.search(r"slipped ([0-9.]+) s behind real time", (base / "server.out").read_text())
    return float(m.group(1)) if m else None


def start(base: Path, args: list[str]) -> tuple[Path, subprocess.Popen]:
    """Start a server with ``args`` (``--links base/links`` added); wait for its map."""
    links = base / "links"
    cmd = [sys.executable, "-m", "laboratory.cli", "serve", *args, "--links", str(links)]
    with open(base / "server.out", "w") as out, open(base / "server.err", "w") as err:
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, stdin=subprocess.DEVNULL)
    deadline = time.monotonic() + START_DEADLINE_S
    map_path = links / link_map.FILENAME
    while not map_path.exists():
        if proc.poll() is not None:
            pytest.fail(f"server exited {proc.returncode}: {text(base / 'server.err')}")
        if time.monotonic() > deadline:
            stop(proc)
            pytest.fail(f"no {map_path} within {START_DEADLINE_S} s: {text(base)}")
        time.sleep(0.05)
    return links, proc


@contextmanager
def serving(base: Path, args: list[str]) -> Iterator[tuple[Path, list, subprocess.Popen]]:
    """A running server with ``args`` (``--links`` is added); see the module doc."""
    links, proc = start(base, args)
    try:
        yield links, link_map.read(links / link_map.FILENAME), proc
        assert proc.poll() is None, f"server died: {text(base / 'server.err')}"
    finally:
        code = stop(proc)
    assert code == 0, f"server exit status {code}: {text(base / 'server.err')}"
    assert not any(links.iterdir()), f"left behind: {sorted(p.name for p in links.iterdir())}"
    assert "stopped at t =" in text(base / "server.out")
