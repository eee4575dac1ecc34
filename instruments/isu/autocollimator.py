"""Two-axis autocollimator (serial): azimuth and zenith of a mirror normal in its field of view.

Angles follow Chart III-3: zenith theta from up; azimuth alpha from east towards north
(E.M = cos(alpha) sin(theta), N.M = sin(alpha) sin(theta)).

Protocol:
  AIM <az_deg> <zen_deg>   point the optical axis (|az| <= 3600)          -> OK
  AIM?                     present pointing
  MEAS?                    "<az_deg> <zen_deg>" of the mirror normal, or ERR 30 NO RETURN
                           when no mirror is within the field of view
"""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import Any

import numpy as np
import simpy

from instruments.base import ByteInstrument, Deferred, InstrumentError, as_float, as_real_in
from instruments.isu.params import AutocollimatorParams
from sim import units
from sim.isu.world import World
from sim.rng import stream
from sim.timebase import ticks

MAX_AZIMUTH_DEG = 3600.0  # largest |azimuth| of AIM, taken modulo 360 (ten turns)


def direction(az: float, zen: float) -> np.ndarray:
    """Unit vector (up, east, north) from azimuth and zenith in radians."""
    return np.array([math.cos(zen), math.cos(az) * math.sin(zen), math.sin(az) * math.sin(zen)])


def angles(v: np.ndarray) -> tuple[float, float]:
    """(azimuth, zenith) in radians of a unit vector (up, east, north); azimuth in [0, 2 pi)."""
    zen = math.acos(max(-1.0, min(1.0, float(v[0]))))
    az = math.atan2(float(v[2]), float(v[1])) % (2 * math.pi)
    return az, zen


class Autocollimator(ByteInstrument):
    def __init__(
        self, name: str, index: int, world: World, p: AutocollimatorParams, latency_s: float
    ) -> None:
        super().__init__(name, world.env, latency_s)
        self.ident = f"ISU-LAB,AC-2,{index},1.0"
        self.world = world
        self.p = p
        self.index = index
        az, zen = p.initial_aim_deg[index - 1]
        self.aim = (math.radians(az), math.radians(zen))
        self._n = 0
        self.define("AIM <az_deg> <zen_deg>", self._aim)
        self.define("AIM?", lambda _: f"{math.degrees(self.aim[0]):.6f} "
                                      f"{math.degrees(self.aim[1]):.6f}")
        self.define("MEAS?", self._meas)
        self.define("TEST?", lambda _: "PASS")

    def measure(self) -> tuple[float, float] | None:
        """Noisy (az, zen) of the mirror normal in the field of view, or None."""
        axis = direction(*self.aim)
        fov = math.radians(self.p.fov_deg)
        seen = [m for m in self.world.mirror_normals(self.world.now) if m @ axis > math.cos(fov)]
        if len(seen) != 1:
            return None
        rng = stream(self.world.seed, "autocollimator", self.index, self._n)
        self._n += 1
        az, zen = angles(seen[0])
        s = units.arcsec(self.p.noise_arcsec)
        # Noise of s on each of two orthogonal directions across the line of sight.
        return az + rng.normal(0.0, s) / max(math.sin(zen), 1e-6), zen + rng.normal(0.0, s)

    def _aim(self, args: list[str]) -> str:
        az = as_real_in(args[0], "azimuth", -MAX_AZIMUTH_DEG, MAX_AZIMUTH_DEG) % 360.0
        zen = as_float(args[1], "zenith")
        lo, hi = self.p.zenith_range_deg
        if not lo <= zen <= hi:
            raise InstrumentError(13, f"zenith {zen:g} outside mount range [{lo}, {hi}] deg")
        self.aim = (math.radians(az), math.radians(zen))
        return "OK"

    def _meas(self, _: list[str]) -> Deferred:
        d = Deferred(self.env)

        def integrate() -> Generator[simpy.Event, Any, None]:
            yield self.env.timeout(ticks(self.p.integration_s)) | d.cancel_event
            if d.cancelled:  # a *CLS dropped the query: nothing to measure
                return
            try:
                m = self.measure()
            except Exception as e:  # noqa: BLE001 - a fault of the simulation, named
                d.resolve(self.internal_error("MEAS?", e))
                return
            if m is None:
                d.resolve(self._error(30, "NO RETURN"))
            else:
                d.resolve(f"{math.degrees(m[0]) % 360.0:.7f} {math.degrees(m[1]):.7f}")

        self.env.process(integrate())
        return d
