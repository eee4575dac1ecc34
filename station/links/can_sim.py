"""python-can interface ``sim``: a CAN bus onto a simulated IEU, in virtual time.

Registered through the ``can.interface`` entry point (pyproject.toml). Message timestamps
are simulated seconds; ``recv(timeout)`` advances the simulation inline.
"""

from __future__ import annotations

from typing import Any

import can

from sim.timebase import seconds, ticks
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
        # no channel on the message (the bus has one: channel_info): a CAN log's writer
        # parses a channel name for its number on every frame, and "sim://ieu" has none,
        # so the log is the same (issue 17: 6,040 frames a day)
        return can.Message(timestamp=t, arbitration_id=fid, data=data, is_extended_id=False)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """Next frame passing the filters, waiting at most ``timeout`` simulated seconds.

        A frame is handed over at its timestamp, never before: the IEU puts a sample's five
        frames out at once, stamped one frame gap apart, and reading the last of them brings
        the simulation to its time (``virtual.advance_to``)."""
        out = self._ep.output
        env = self._env
        deadline = None if timeout is None else int(env.now) + ticks(timeout)
        while True:
            if not out:
                left = None if deadline is None else seconds(max(0, deadline - env.now))
                virtual.run_until(env, lambda: len(out) > 0, left)
                if not out:
                    return None
            due = ticks(out[0][0])
            if due > env.now:  # stamped ahead of the clock
                if deadline is not None and due > deadline:
                    virtual.advance_to(env, deadline)
                    return None
                virtual.advance_to(env, due)
                continue  # the frame at the head may have changed meanwhile
            msg = self._take()
            if msg is not None and self._matches_filters(msg):
                return msg

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return self.recv(timeout), True

    def shutdown(self) -> None:
        super().shutdown()
