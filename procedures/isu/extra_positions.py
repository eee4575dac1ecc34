"""Extra accelerometer positions beyond the manual (issue 19, our design): after Chart
II-14, static positions set as positions 7-15 (II-5's scheme: phi1 = 0, phi2 = 90, level
corrections) but with each accelerometer's input axis tilted from vertical by the options'
angles, both signs, so that the odd part of Chart IV-1 separates D1 and D3 at several input
levels, as the bisector positions 13, 14 (Chart II-14) do at one.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from procedures.isu.accel_static import COUNTERS, accel_kind
from procedures.isu.calibration.geometry import frame_at, setting_for
from procedures.isu.calibration.inputs import EXTRA_FIRST
from procedures.isu.sheets import (
    CounterOutputs,
    CounterSettings,
    PositionSetting,
    ResolverSettings,
)
from procedures.isu.static_positions import Uncorrected, pair_steps, run_static
from procedures.runner import Run

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

CHART = "II-14E"  # ours, not the manual's: the extension of Chart II-14
TITLE = "Accelerometer scale factor and third order, tilted positions (beyond the manual)"

SET_S = 25.0  # setting the table with level corrections, about (a default day's positions)
E3 = np.eye(3)


def tilted_ups(tilts_deg: list[float] | tuple[float, ...]) -> list[np.ndarray]:
    """Body vectors put up, in pairs +-u: per tilt theta and accelerometer k,
    u = cos theta B_k + sin theta B_k+1 (k + 1 cyclic), accelerometer k at cos theta and k + 1
    at sin theta (of g). At 45 deg a pair tilts both by 45: the pairs of k = 1, 2 then tilt
    all three accelerometers, and the third pair is left out (four positions, not six)."""
    out = []
    for th in tilts_deg:
        c, s = math.cos(math.radians(th)), math.sin(math.radians(th))
        for k in ((0, 1) if math.isclose(th, 45.0) else (0, 1, 2)):
            u = c * E3[k] + s * E3[(k + 1) % 3]
            out += [u, -u]
    return out


def extra_numbers(tilts_deg: tuple[float, ...]) -> list[int]:
    """Position numbers of the extra positions: 16 on, in ``tilted_ups`` order."""
    return list(range(EXTRA_FIRST, EXTRA_FIRST + len(tilted_ups(tilts_deg))))


def extra_settings(tilts_deg: tuple[float, ...], t_bi: np.ndarray) -> dict[int, dict]:
    """Per extra position: resolver setting (phi3, phi4, deg; the second of each pair is
    the first with phi3 + 180 deg, as positions 8, 10, 12) and the nominal body up and north
    (Chart I-4 chain from the survey's T^BI)."""
    out = {}
    ups = tilted_ups(tilts_deg)
    for i, m in enumerate(extra_numbers(tilts_deg)):
        if i % 2 == 0:
            p3, p4 = setting_for(ups[i], t_bi)
        else:
            p3 += math.pi
        fr = frame_at(t_bi, p3, p4)
        out[m] = {"setting_deg": (math.degrees(p3) % 360.0, math.degrees(p4)),
                  "up": tuple(float(x) for x in fr[:, 0]),
                  "north": tuple(float(x) for x in fr[:, 1])}
    return out


def extra_accel_positions(st: IsuDrivers, run: Run, t_bi: np.ndarray,
                          tilts_deg: tuple[float, ...], vertical_s: float,
                          outputs: CounterOutputs, f0: float,
                          uncorrected: Uncorrected | None = None,
                          precision_arcsec: float = 0.0) -> dict[int, dict]:
    """The extra chart (after Chart II-14, as it: bubble corrections, "measure X-Y"): every
    string counted over the plan's vertical gate, the scale factor's; the outputs go to the
    Counter Outputs Sheet as rows "accel 16" on; each record carries its setting and the
    nominal up and north, which the all-positions fit models."""
    geo = extra_settings(tilts_deg, t_bi)
    settings = ResolverSettings(positions={
        str(m): PositionSetting(phi1=0.0, phi2=90.0, phi3=g["setting_deg"][0],
                                phi4=g["setting_deg"][1], bubble_correction=True)
        for m, g in geo.items()})
    preset = int(math.ceil(vertical_s * f0))
    presets = CounterSettings(
        presets={f"accel {m}": {str(c): preset for c in COUNTERS} for m in geo},
        basis={"accelerometer 16 on": f"{vertical_s / 60:g} min, the vertical gate"})
    run.save_sheet("extra_resolver_settings", settings)
    steps = pair_steps(list(geo)[::2])
    data = run_static(st, run, CHART, TITLE, accel_kind(f0), settings, presets, outputs,
                      steps, uncorrected, precision_arcsec)
    return {m: {**d, **geo[m]} for m, d in data.items()}
