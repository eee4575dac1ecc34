"""The fuzzing harness shared by bench/fuzz.py and the per-area target modules.

A target turns one random draw into one input, feeds it to one parser (an instrument's
command parser, a driver's reply parser, the IEU frame path, a CAN server, the ESG
data-line parser) and classifies what came back:

* ``"accepted"``: a well-formed input, taken with the right value;
* ``"rejected"``: a malformed input refused the project's way (an error reply, a
  ``StationError``/``DriverError``, a logged and discarded line);
* ``"wrong"``: a malformed input taken as a value (a syntax the protocol defines was not
  checked), or a well-formed one taken with the wrong value.

An exception escaping ``run`` is an *escaped exception* (a builtin reaching the caller);
a ``run`` that does not return within ``hang_s`` is a *hang*. Area modules are
``bench/fuzz_<area>.py``, each with ``TARGETS: list[FuzzTarget]``.
"""

from __future__ import annotations

import random
import signal
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

KINDS = ("accepted", "rejected", "wrong")


@dataclass
class FuzzTarget:
    name: str
    run: Callable[[random.Random], str]  # one input from the draw; returns a KINDS member
    setup: Callable[[], None] | None = None  # once, before the inputs
    teardown: Callable[[], None] | None = None  # once, after them


@dataclass
class FuzzReport:
    name: str
    inputs: int = 0
    kinds: Counter = field(default_factory=Counter)
    escaped: Counter = field(default_factory=Counter)  # exception type -> count
    hangs: int = 0
    examples: dict[str, str] = field(default_factory=dict)  # outcome -> first seed seen

    def line(self) -> str:
        esc = sum(self.escaped.values())
        return (f"{self.name:<34} inputs {self.inputs:>8}  accepted {self.kinds['accepted']:>8}"
                f"  rejected {self.kinds['rejected']:>8}  escaped {esc:>4}  hangs {self.hangs:>3}"
                f"  wrong-value-accepted {self.kinds['wrong']:>4}")


class _Hang(Exception):
    pass


def _alarm(signum, frame):  # noqa: ARG001 - signal handler signature
    raise _Hang


def run_target(target: FuzzTarget, n: int, seed: int, hang_s: float = 2.0) -> FuzzReport:
    """Feed ``n`` inputs to ``target``; input i is drawn from ``Random(seed * 10**9 + i)``."""
    rep = FuzzReport(target.name)
    if target.setup:
        target.setup()
    old = signal.signal(signal.SIGALRM, _alarm)
    try:
        for i in range(n):
            rng = random.Random(seed * 1_000_000_000 + i)
            rep.inputs += 1
            signal.setitimer(signal.ITIMER_REAL, hang_s)
            try:
                kind = target.run(rng)
            except _Hang:
                rep.hangs += 1
                rep.examples.setdefault("hang", f"input {i}")
                continue
            except Exception as e:  # noqa: BLE001 - counting what escapes is the point
                rep.escaped[type(e).__name__] += 1
                rep.examples.setdefault(f"escaped {type(e).__name__}", f"input {i}: {e}")
                continue
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            if kind not in KINDS:
                raise ValueError(f"target {target.name} returned {kind!r}")
            rep.kinds[kind] += 1
            if kind == "wrong":
                rep.examples.setdefault("wrong", f"input {i}")
    finally:
        signal.signal(signal.SIGALRM, old)
        if target.teardown:
            target.teardown()
    return rep
