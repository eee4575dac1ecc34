"""Driver of a two-axis autocollimator."""

from __future__ import annotations

from station.clock import Clock
from station.drivers.replies import Form, angle_between, fixed
from station.drivers.serial_base import SerialDriver
from station.errors import InstrumentRefused

NO_RETURN = 30
# instruments.autocollimator of the default configuration (docs/protocols.md): the mount's
# zenith range and the field of view about the optical axis
ZENITH_RANGE_DEG = (60.0, 120.0)
FOV_DEG = 0.5
READING_SLACK_DEG = 10.0 / 3600.0  # 10 arcsec: ten sigma of the 1 arcsec reading noise

POINTING = Form([fixed("azimuth, deg", 6, 0.0, 360.0),
                 fixed("zenith, deg", 6, *ZENITH_RANGE_DEG)])
MEASUREMENT = Form([
    fixed("azimuth, deg", 7, 0.0, 360.0),
    fixed("zenith, deg", 7, ZENITH_RANGE_DEG[0] - FOV_DEG - READING_SLACK_DEG,
          ZENITH_RANGE_DEG[1] + FOV_DEG + READING_SLACK_DEG),
])


class AutocollimatorDriver(SerialDriver):
    model = ("ISU-LAB", "AC-2")

    def __init__(self, name: str, url: str, clock: Clock | None = None,
                 timeout: float = 5.0) -> None:
        super().__init__(name, url, clock, timeout)
        # the pointing as last set or read, (az, zen) deg; None until known
        self.aimed: tuple[float, float] | None = None

    def aim(self, az_deg: float, zen_deg: float) -> None:
        cmd = f"AIM {az_deg:.6f} {zen_deg:.6f}"
        self.aimed = None  # unknown until the instrument has taken it
        self.command(cmd)
        az, zen = (float(x) for x in cmd.split()[1:])
        self.aimed = (az % 360.0, zen)

    def pointing(self) -> tuple[float, float]:
        az, zen = self.ask("AIM?", POINTING)
        self.aimed = (az, zen)
        return az, zen

    def measure(self) -> tuple[float, float] | None:
        """(azimuth, zenith) of the mirror normal in view, deg; None when no mirror returns.

        A return must lie within the field of view of the pointing (when the driver knows
        it), else within the field of view of the mount's zenith range."""
        try:
            az, zen = self.ask("MEAS?", MEASUREMENT)
        except InstrumentRefused as e:
            if e.code == NO_RETURN and e.text == "NO RETURN":
                return None
            raise
        if self.aimed is not None:
            off = angle_between(az, zen, *self.aimed)
            if off > FOV_DEG + READING_SLACK_DEG:
                raise self.refuse("MEAS?", f"{off:.4f} deg from the pointing "
                                  f"({self.aimed[0]:.6f}, {self.aimed[1]:.6f}), outside the "
                                  f"{FOV_DEG:g} deg field of view")
        return az, zen
