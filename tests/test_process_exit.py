"""laboratory.process_exit: a `station` process ends as exit would end it (handlers run,
streams flushed, the exit code kept) without the interpreter's teardown, and falls back to
the ordinary exit while a non-daemon thread runs (issue 17)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _child(code: str) -> subprocess.Popen[str]:
    """``code`` in a child whose stdout is buffered (as on a user's machine: not unbuffered
    by PYTHONUNBUFFERED), with pipes for its three streams."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    return subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, text=True, env=env,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)


def test_handlers_run_and_streams_flushed_with_the_code() -> None:
    p = _child("import atexit, sys\n"
               "from laboratory.process_exit import finish\n"
               "atexit.register(lambda: print('handler'))\n"
               "sys.stdout.write('x' * 100000)\n"
               "sys.stderr.write('to stderr')\n"
               "finish(3)\n")
    out, err = p.communicate()
    assert p.returncode == 3
    assert out == "x" * 100000 + "handler\n"
    assert err == "to stderr"


def test_a_running_thread_is_waited_for() -> None:
    # the thread writes only after the parent answers "ready", which the child prints just
    # before finish: an exit that did not wait would lose the thread's line
    p = _child("import sys, threading\n"
               "from laboratory.process_exit import finish\n"
               "def late():\n"
               "    sys.stdin.readline()\n"
               "    print('thread done', flush=True)\n"
               "threading.Thread(target=late).start()\n"
               "print('ready', flush=True)\n"
               "finish(0)\n")
    assert p.stdout is not None and p.stdin is not None
    assert p.stdout.readline() == "ready\n"
    p.stdin.write("go\n")
    p.stdin.close()
    assert p.stdout.read() == "thread done\n"
    assert p.wait() == 0


def test_an_unflushable_stdout_is_a_failure() -> None:
    p = _child("import sys\n"
               "from laboratory.process_exit import finish\n"
               "sys.stdout.write('lost')\n"  # buffered: a pipe is not a terminal
               "sys.stdin.readline()\n"
               "finish(0)\n")
    assert p.stdout is not None and p.stdin is not None
    p.stdout.close()  # the reader is gone before the child flushes
    p.stdin.write("go\n")
    p.stdin.close()
    assert p.wait() == 120


def test_a_process_started_without_stdout_ends_as_exit_ends_it() -> None:
    # descriptor 1 closed at start: Python sets sys.stdout to None, and exit passes over it
    code = ("import atexit, sys\n"
            "from laboratory.process_exit import finish\n"
            "assert sys.stdout is None\n"
            "atexit.register(lambda: sys.stderr.write('handler'))\n"
            "finish(0)\n")
    p = subprocess.run(["sh", "-c", f'"{sys.executable}" -c "$0" >&-', code], cwd=ROOT,
                       capture_output=True, text=True, check=False)
    assert (p.returncode, p.stderr) == (0, "handler")


def test_the_station_script_keeps_exit_codes_and_output() -> None:
    def station(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "laboratory.cli", *args], cwd=ROOT,
                              capture_output=True, text=True, check=False)

    ok = station("--help")
    assert ok.returncode == 0 and "Usage:" in ok.stdout and "day" in ok.stdout
    bad = station("day", "--seed", "x")
    assert bad.returncode == 2 and bad.stderr.startswith("error: ") and "--seed" in bad.stderr
    assert bad.stdout == ""
