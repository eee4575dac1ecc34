"""Fuzz targets for the serial instruments' command parsers (one per instrument kind).

Each input is one command line drawn by tests/instrument_grammar.py: a valid line (a third)
or a mutated one (extra or missing arguments, ``1_000``, ``+5``, unicode digits, changed
words, stray bytes, over-long lines...). The line goes through the instrument's ``receive``
as a host's bytes would; the reply it queued is judged against the documented grammar:

* a line the grammar calls invalid must get an ``ERR <code>`` reply (never ``OK``, a value
  or a deferred answer, never ERR 200, the internal fault);
* a valid line must get the documented reply, or a refusal that depends only on the
  instrument's state (busy, interlock, wiring, standby...);
* a blank line gets no reply.

The output queue is cleared after each input and simulated time advances 5 ms, so motions,
integrations and counter gates run while the inputs keep coming.

    python bench/fuzz.py 100000 --only instrument
"""

from __future__ import annotations

import random
import sys
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from fuzz_core import FuzzTarget  # noqa: E402
from instrument_grammar import GRAMMARS, Grammar  # noqa: E402

from instruments.base import ByteInstrument, Deferred  # noqa: E402
from sim.timebase import ticks  # noqa: E402

STEP = ticks(0.005)  # simulated time between inputs
CLEAN_EVERY = 1000  # inputs between emptying the instrument's wire buffer


def _isu(name: str) -> Callable[[], tuple[ByteInstrument, Callable[[], None]]]:
    def build():
        from station.config.isu import load_config
        from station.racks.isu import SimulatedRack

        rack = SimulatedRack(load_config())
        if name == "counter1":  # wired as the calibration wires it: gates can open
            panel = rack.serial["patch_panel"]
            panel.receive(b"CONN OSC1 C1 X\nCONN OSC2 C1 Z\n")
            panel.clear_output()
        return rack.serial[name], rack.close
    return build


def _cigtf(name: str):
    def build():
        from station.racks.cigtf import CigtfRack

        rack = CigtfRack(1)
        return rack.serial[name], rack.close
    return build


def _esg(name: str):
    def build():
        from station.racks.esg import EsgRack

        rack = EsgRack(1)
        return rack.serial[name], rack.close
    return build


def judge_one(inst: ByteInstrument, grammar: Grammar, raw: bytes) -> str:
    """Send ``raw`` as one line and judge the reply it queued (see the module docstring)."""
    inst.receive(raw + b"\n")
    queued = inst.pending()
    if len(queued) > 1:
        return "wrong"  # one line, one reply
    reply: str | None = None
    deferred = False
    if queued:
        item = queued[0]
        if isinstance(item, Deferred):
            if item.event.triggered:
                reply = item.event.value
            else:
                deferred = True
        else:
            reply = item
    return grammar.judge(raw, reply, deferred)


def target(label: str, grammar: str, build) -> FuzzTarget:
    state: dict = {}
    g = GRAMMARS[grammar]

    def setup() -> None:
        state["inst"], state["close"] = build()
        state["n"] = 0

    def run(rng: random.Random) -> str:
        inst = state["inst"]
        kind = judge_one(inst, g, g.draw_line(rng))
        inst.clear_output()
        inst.env.run(until=inst.env.now + STEP)
        state["n"] += 1
        if state["n"] % CLEAN_EVERY == 0:
            inst.output.clear()
        return kind

    def teardown() -> None:
        state["close"]()

    return FuzzTarget(f"instrument {label}", run, setup, teardown)


TARGETS: list[FuzzTarget] = [
    target("table", "table", _isu("table")),
    target("patch_panel", "patch_panel", _isu("patch_panel")),
    target("counter", "counter", _isu("counter1")),
    target("autocollimator", "autocollimator", _isu("autocollimator1")),
    target("bubble_levels", "bubble_levels", _isu("bubble_levels")),
    target("oscillator", "oscillator", _isu("oscillator")),
    target("cigtf fixture", "fixture", _cigtf("fixture")),
    target("cigtf dvm", "dvm", _cigtf("dvm")),
    target("cigtf gyro_power", "gyro_power", _cigtf("gyro_power")),
    target("esg processor", "processor", _esg("processor")),
    target("esg head", "head", _esg("head")),
    target("esg turntable", "turntable", _esg("turntable")),
    target("esg theodolite", "theodolite", _esg("theodolite")),
    target("esg console", "console", _esg("console")),
]
