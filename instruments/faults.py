"""Fault injection for rehearsals: simulated instruments that misbehave as configured.

The faults act inside the instruments, never in the links, so a rack stepped in virtual
time (``station day``) and the same rack served in real time over ptys and CAN misbehave
alike. Every random choice draws from a :func:`sim.rng.stream` named after the instrument
and the fault, so the same seed and configuration give the same faults, byte for byte,
whatever else the run does.

Serial instruments: each reply is delayed by ``latency_s`` more, each of its bytes may get
one bit flipped (``corrupt_rate``) and may then be lost (``drop_rate``). The IEU: each frame
it sends is delayed, may be lost, and may have one data byte altered. ``silent_after_s``
stops an instrument sending anything from then on (it still listens). The table's
``stall_axis`` seizes one drive at ``stall_after_s``.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Mapping
from functools import partial
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import simpy
from pydantic import BaseModel, ConfigDict, Field

from instruments.base import ByteInstrument
from instruments.output_faults import FrameFault, ReplyFault
from sim.timebase import ticks

if TYPE_CHECKING:  # the config reads FaultSpec: keep the IEU and its CAN database unloaded
    from instruments.isu.ieu import Ieu

MAX_RUN_S = 1e6  # s: no run of any laboratory lasts this long (the longest is 52 h)
TABLE_ONLY_FAULTS = ("stall_axis", "stall_after_s")


class FaultSpec(BaseModel):
    """Faults of one instrument for a rehearsal (``[faults.<instrument>]``); defaults: none.

    Applied inside the simulated instruments, so a virtual run and a served rack misbehave
    alike; every random choice is seeded from the run's seed. The station config
    (station.config.isu) reads a table of these, one per instrument name.
    """

    model_config = ConfigDict(defer_build=True,
                              extra="forbid", frozen=True, allow_inf_nan=False, strict=True)
    # Extra delay per reply / frame. Past a minute (twelve times the drivers' 5 s reply
    # timeout) a late reply is silence: rehearse that with silent_after_s.
    latency_s: float = Field(0.0, ge=0, le=60.0)
    drop_rate: float = Field(0.0, ge=0, lt=1)  # serial: per reply byte; IEU: per frame
    corrupt_rate: float = Field(0.0, ge=0, lt=1)  # serial: one bit per byte; IEU: one byte
    silent_after_s: float | None = Field(None, ge=0, le=MAX_RUN_S)  # sends nothing after
    stall_axis: int | None = Field(None, ge=1, le=4)  # table only: the axis whose drive seizes
    stall_after_s: float = Field(0.0, ge=0, le=MAX_RUN_S)  # table only: when it seizes


@runtime_checkable
class AxisDrives(Protocol):
    """An instrument with drives that can seize (the ISU's table controller)."""

    def stall(self, axis: int) -> None: ...


def at(env: simpy.Environment, t_s: float, action: Callable[[], None]) -> None:
    """Run ``action`` at simulated time ``t_s`` (at once if that time has passed)."""
    t = ticks(t_s)
    if env.now >= t:
        action()
        return

    def wait() -> Generator[simpy.Event, Any, None]:
        yield env.timeout(t - env.now)
        action()

    env.process(wait())


def _silence(inst: ByteInstrument | Ieu) -> Callable[[], None]:
    def action() -> None:
        inst.silent = True

    return action


def apply_faults(serial: Mapping[str, ByteInstrument], ieu: Ieu,
                 faults: Mapping[str, FaultSpec], seed: int) -> None:
    """Arm each configured fault on its instrument; nothing at all when ``faults`` is empty."""
    env = ieu.env
    for name, f in faults.items():
        if name == ieu.name:
            inst: ByteInstrument | Ieu = ieu
        elif name in serial:
            inst = serial[name]
        else:
            raise ValueError(f"fault for unknown instrument {name!r}")
        if f.latency_s or f.drop_rate or f.corrupt_rate:
            lossy = (name, seed, f.latency_s, f.drop_rate, f.corrupt_rate)
            if isinstance(inst, ByteInstrument):
                inst.reply_fault = ReplyFault(*lossy)
            else:
                inst.frame_fault = FrameFault(*lossy)
        if f.silent_after_s is not None:
            at(env, f.silent_after_s, _silence(inst))
        if f.stall_axis is not None:
            if not isinstance(inst, AxisDrives):
                raise ValueError(f"{name} has no axis to stall")
            at(env, f.stall_after_s, partial(inst.stall, f.stall_axis))
