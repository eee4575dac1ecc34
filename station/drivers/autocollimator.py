"""Driver of a two-axis autocollimator."""

from __future__ import annotations

from station.drivers.serial_base import SerialDriver
from station.errors import InstrumentRefused

NO_RETURN = 30


class AutocollimatorDriver(SerialDriver):
    def aim(self, az_deg: float, zen_deg: float) -> None:
        self.command(f"AIM {az_deg:.6f} {zen_deg:.6f}")

    def pointing(self) -> tuple[float, float]:
        az, zen = self.numbers("AIM?", 2)
        return az, zen

    def measure(self) -> tuple[float, float] | None:
        """(azimuth, zenith) of the mirror normal in view, deg; None when no mirror returns."""
        try:
            az, zen = self.numbers("MEAS?", 2)
        except InstrumentRefused as e:
            if e.code == NO_RETURN:
                return None
            raise
        return az, zen
