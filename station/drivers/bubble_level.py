"""Driver of the table's bubble levels."""

from __future__ import annotations

from station.drivers.serial_base import SerialDriver


class BubbleLevelDriver(SerialDriver):
    def corrections(self) -> tuple[float, float]:
        """Level corrections to add to phi1 and phi3, arcsec."""
        c1, c3 = self.numbers("LEV?", 2)
        return c1, c3
