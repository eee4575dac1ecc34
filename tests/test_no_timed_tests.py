"""No test asserts on wall-clock time: machines differ, so speed lives in bench/ scripts.

Checked on the source (AST) of every file under tests/: an ``assert`` (or a
``pytest.approx``/comparison inside one) may not use a value derived from a wall-clock
reading (``time.time``, ``perf_counter``, ``monotonic``, ``process_time``, ``datetime.now``)
nor a record's ``wall_seconds``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
WALL_CALLS = {"time", "time_ns", "perf_counter", "perf_counter_ns", "monotonic",
              "monotonic_ns", "process_time", "process_time_ns"}
# only on datetime: a station clock's now() is simulated time
DATETIME_CALLS = {"now", "utcnow", "today"}
WALL_KEYS = {"wall_seconds", "wall_s", "elapsed", "elapsed_s"}


def _reads_wall_clock(node: ast.AST, tainted: set[str]) -> bool:
    for sub in ast.walk(node):
        if isinstance(sub, ast.Call):
            f = sub.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
            if name in WALL_CALLS:
                return True
            if (name in DATETIME_CALLS and isinstance(f, ast.Attribute)
                    and "datetime" in ast.unparse(f.value)):
                return True
        if isinstance(sub, ast.Name) and sub.id in tainted:
            return True
        if isinstance(sub, ast.Constant) and sub.value in WALL_KEYS:
            return True
        if isinstance(sub, ast.Attribute) and sub.attr in WALL_KEYS:
            return True
    return False


def timed_asserts(tree: ast.AST) -> list[int]:
    """Line numbers of asserts that depend on a wall-clock reading (per function scope)."""
    bad: list[int] = []
    scopes = [n for n in ast.walk(tree)
              if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Module))]
    for scope in scopes:
        tainted: set[str] = set()
        for _ in range(3):  # propagate through t1 - t0, rows of elapsed, ...
            for n in ast.walk(scope):
                if isinstance(n, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
                    value = n.value
                    targets = n.targets if isinstance(n, ast.Assign) else [n.target]
                    if value is not None and _reads_wall_clock(value, tainted):
                        for t in targets:
                            tainted |= {x.id for x in ast.walk(t) if isinstance(x, ast.Name)}
        bad += [n.lineno for n in ast.walk(scope)
                if isinstance(n, ast.Assert) and _reads_wall_clock(n.test, tainted)]
    return sorted(set(bad))


@pytest.mark.parametrize("path", sorted(TESTS.glob("*.py")), ids=lambda p: p.name)
def test_no_wall_clock_assertion(path: Path) -> None:
    lines = timed_asserts(ast.parse(path.read_text(encoding="utf-8")))
    assert not lines, f"{path.name}: wall-clock assertion at line(s) {lines}"


def test_the_check_catches_a_timed_assert() -> None:
    src = ("import time\n"
           "def test_x():\n"
           "    t0 = time.perf_counter()\n"
           "    work()\n"
           "    dt = time.perf_counter() - t0\n"
           "    assert dt < 1.0\n"
           "def test_y(res):\n"
           "    assert res['wall_seconds'] == 2.0\n"
           "def test_z(clock):\n"
           "    assert clock.now() == 3.0\n"
           "def test_w():\n"
           "    t = datetime.datetime.now()\n"
           "    assert t.hour < 23\n")
    assert timed_asserts(ast.parse(src)) == [6, 8, 13]
