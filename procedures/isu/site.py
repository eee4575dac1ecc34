"""The laboratory's site as its procedures know it: latitude, local gravity, Earth rate.

Report 000 writes lambda for the colatitude, so omega^E sin lambda is the Earth rate's north
component and omega^E cos lambda its vertical one (Chart I-2 step 3 enters both, with g in
g units). The simulator keeps its own site (``sim.isu.environment.Site``); this is the value
the check-sheets are given, built once by the application from the station config.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from procedures.isu.alignment.estimation import G0


@dataclass(frozen=True)
class Site:
    """Latitude (deg), local gravity (m/s^2) and the Earth's rate (deg/hr) of the laboratory."""

    latitude_deg: float
    g_local_mps2: float
    earth_rate_deg_per_hr: float

    def __post_init__(self) -> None:
        for name in ("latitude_deg", "g_local_mps2", "earth_rate_deg_per_hr"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ValueError(f"site.{name}: must be a finite number, got {v!r}")
        if not -90.0 <= self.latitude_deg <= 90.0:
            raise ValueError(f"site.latitude_deg: {self.latitude_deg:g} is not a latitude "
                             "(-90 to 90 deg)")
        for name in ("g_local_mps2", "earth_rate_deg_per_hr"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"site.{name}: must be positive, got {getattr(self, name):g}")

    @property
    def g(self) -> float:
        """Local gravity in g units (the lab's coefficients are per g)."""
        return self.g_local_mps2 / G0

    @property
    def omega_sin_lambda(self) -> float:
        """omega^E sin(colatitude), deg/hr: the Earth rate's north component."""
        return self.earth_rate_deg_per_hr * math.cos(math.radians(self.latitude_deg))

    @property
    def omega_cos_lambda(self) -> float:
        """omega^E cos(colatitude), deg/hr: the Earth rate's vertical component."""
        return self.earth_rate_deg_per_hr * math.sin(math.radians(self.latitude_deg))
