"""The end of a child process the station started (the plot child, git asked for run.json):
killed if it still runs, reaped, and its pipes closed, so that no process or descriptor
outlives the command that started it."""

from __future__ import annotations

import subprocess
from typing import Any


def ended(p: subprocess.Popen[Any]) -> None:
    """``p`` killed (if it still runs), reaped, and its pipes closed."""
    if p.poll() is None:
        p.kill()
    p.wait()
    for f in (p.stdin, p.stdout, p.stderr):
        if f is not None:
            try:
                f.close()
            except OSError:
                pass
