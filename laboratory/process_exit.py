"""The end of a `station` process: what exit does, without the interpreter's teardown.

A command's own work ends with its files closed (records are written through context
managers and synced). What the interpreter does after that is free some 600 modules'
objects one by one, memory the operating system takes back at once: 0.05-0.1 s of every
command's wall time (issue 17). ``finish`` runs the exit handlers (atexit: logging,
finalizers, coverage) and flushes the standard streams, as exit would, then ends the
process. It falls back to the ordinary exit where that could lose something: a
non-daemon thread still running (exit would wait for it).
"""

from __future__ import annotations

import atexit
import os
import sys
import threading
from typing import NoReturn

BROKEN_STDOUT = 120  # what the interpreter exits with when it cannot flush stdout


def _others_running() -> bool:
    """A non-daemon thread besides this one still runs: exit would join it."""
    me = threading.current_thread()
    return any(t is not me and t.is_alive() and not t.daemon for t in threading.enumerate())


def finish(rc: int) -> NoReturn:
    """End the process with ``rc`` as exit would (handlers run, streams flushed), skipping
    the modules' teardown; an unflushable stdout turns a success into 120, as exit does."""
    if _others_running():
        sys.exit(rc)
    atexit._run_exitfuncs()  # noqa: SLF001  # what exit runs first; then unregistered
    for stream in (sys.stdout, sys.stderr):
        if stream is None:  # started without the stream (its descriptor closed): as exit
            continue
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe or stream: as exit reports it
            if stream is sys.stdout and rc == 0:
                rc = BROKEN_STDOUT
    os._exit(rc)
