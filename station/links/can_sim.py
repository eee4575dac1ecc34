"""python-can interface ``sim``: a CAN bus onto a simulated IEU, in virtual time.

Registered through the ``can.interface`` entry point (pyproject.toml). Message timestamps
are simulated seconds; ``recv(timeout)`` advances the simulation inline.
"""

from __future__ import annotations

from typing import Any

import can

from sim.timebase import seconds
from station.links import virtual


class SimBus(can.BusABC):
    def __init__(self, channel: str = "ieu", rack: str | None = None, **kwargs: Any) -> None:
        try:
            self._ep, self._env = virtual.resolve_can(str(channel), rack)
        except LookupError as e:
            raise can.CanInitializationError(str(e)) from None
        self.channel_info = f"sim://{channel}"
        super().__init__(channel=channel, **kwargs)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
            raise can.CanOperationError("the IEU bus carries standard data frames only")
        self._ep.receive_frame(msg.arbitration_id, bytes(msg.data))

    def _take(self) -> can.Message | None:
        out = self._ep.output
        if not out:
            return None
        t, fid, data = out.popleft()
        return can.Message(
            timestamp=t,
            arbitration_id=fid,
            data=data,
            is_extended_id=False,
            channel=self.channel_info,
        )

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """Next frame passing the filters, waiting at most ``timeout`` simulated seconds."""
        out = self._ep.output
        env = self._env
        deadline = None if timeout is None else seconds(env.now) + timeout
        while True:
            left = None if deadline is None else max(0.0, deadline - seconds(env.now))
            virtual.run_until(env, lambda: len(out) > 0, left)
            msg = self._take()
            if msg is None:
                return None
            if self._matches_filters(msg):
                return msg

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        out = self._ep.output
        virtual.run_until(self._env, lambda: len(out) > 0, timeout)
        return self._take(), False

    def shutdown(self) -> None:
        super().shutdown()
