"""Driver of the four-axis test-table controller."""

from __future__ import annotations

from station.drivers.replies import Form, fixed, word
from station.drivers.serial_base import SerialDriver
from station.errors import LinkTimeout

AXES = (1, 2, 3, 4)
# table.trunnion_range_deg of the default configuration (docs/protocols.md): axis 1 cannot
# leave it; its resolver may read a little beyond at a limit (overshoot 2 arcsec, resolver
# error 1 arcsec, setting scatter): 0.01 deg of slack
TRUNNION_RANGE_DEG = (-5.0, 95.0)
READING_SLACK_DEG = 0.01
MAX_RATE_DEG_S = 20.0  # table.max_rate_deg_s: RATE and RAMP refuse more
STATES = ("HOLD", "MOVING", "SETTLING", "ACCEL", "ROTATING")

POSITION = {
    1: Form([fixed("axis 1 reading, deg", 7, TRUNNION_RANGE_DEG[0] - READING_SLACK_DEG,
                   TRUNNION_RANGE_DEG[1] + READING_SLACK_DEG)]),
    # axes 2-4 wrap to [0, 360); 7 decimals may round up to 360.0000000
    **{a: Form([fixed(f"axis {a} reading, deg", 7, 0.0, 360.0)]) for a in (2, 3, 4)},
}
RATE = Form([fixed("rate, deg/s", 7, -MAX_RATE_DEG_S, MAX_RATE_DEG_S)])
STATUS = Form([word(f"axis {a} state", *STATES) for a in AXES], sep=",")
INTERLOCK = Form([word("interlock", "CLOSED", "OPEN")])


class TableDriver(SerialDriver):
    model = ("ISU-LAB", "TT-4AX")

    def move(self, axis: int, deg: float) -> None:
        self.command(f"POS {axis} {deg:.7f}")

    def rotate(self, axis: int, rate_deg_s: float) -> None:
        self.command(f"RATE {axis} {rate_deg_s:.7f}")

    def ramp(self, axis: int, accel_deg_s2: float, rate_deg_s: float) -> None:
        self.command(f"RAMP {axis} {accel_deg_s2:.7f} {rate_deg_s:.7f}")

    def stop(self, axis: int | None = None) -> None:
        self.command("STOP" if axis is None else f"STOP {axis}")

    def home(self) -> None:
        self.command("HOME")

    def position(self, axis: int) -> float:
        """Resolver reading of ``axis``, deg (axes 2-4 in [0, 360])."""
        a = self.whole(axis, "axis", 1, 4)
        return self.ask(f"POS? {a}", POSITION[a])[0]

    def positions(self) -> tuple[float, float, float, float]:
        p1, p2, p3, p4 = (self.position(a) for a in AXES)
        return p1, p2, p3, p4

    def rate(self, axis: int) -> float:
        a = self.whole(axis, "axis", 1, 4)
        return self.ask(f"RATE? {a}", RATE)[0]

    def status(self) -> list[str]:
        return list(self.ask("STAT?", STATUS))

    def interlock(self) -> str:
        return self.ask("ILCK?", INTERLOCK)[0]

    def set_pulses_per_rev(self, n: int) -> None:
        self.command(f"PPR {n}")

    def wait_still(self, timeout: float = 120.0, poll: float = 0.5) -> None:
        """Wait until every axis is holding or turning at its commanded rate."""
        clock = self.needs_clock()
        t_end = clock.now() + timeout
        while True:
            st = self.status()
            if all(s in ("HOLD", "ROTATING") for s in st):
                return
            if clock.now() >= t_end:
                late = [f"axis {i} ({s})" for i, s in enumerate(st, start=1)
                        if s not in ("HOLD", "ROTATING")]
                raise LinkTimeout(
                    self.name, self.url,
                    f"{', '.join(late)} not settled after {timeout:g} s; STAT? {','.join(st)}",
                )
            clock.sleep(poll)
