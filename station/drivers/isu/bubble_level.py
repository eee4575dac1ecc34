"""Driver of the table's bubble levels."""

from __future__ import annotations

from station.drivers.replies import Form, fixed
from station.drivers.serial_base import SerialDriver

# instruments.bubble_level.range_arcsec of the default configuration (docs/protocols.md):
# beyond it the levels answer ERR 40; a reading may pass it by its noise (0.2 arcsec,
# 1 sigma): 1 arcsec of slack. A lost decimal point (680.0) lands far outside.
RANGE_ARCSEC = 120.0
READING_SLACK_ARCSEC = 1.0
_LIMIT = RANGE_ARCSEC + READING_SLACK_ARCSEC
CORRECTIONS = Form([fixed("phi1 correction, arcsec", 2, -_LIMIT, _LIMIT),
                    fixed("phi3 correction, arcsec", 2, -_LIMIT, _LIMIT)])


class BubbleLevelDriver(SerialDriver):
    model = ("ISU-LAB", "BL-2")

    def corrections(self) -> tuple[float, float]:
        """Level corrections to add to phi1 and phi3, arcsec."""
        c1, c3 = self.ask("LEV?", CORRECTIONS)
        return c1, c3
