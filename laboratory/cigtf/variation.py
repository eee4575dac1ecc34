"""`station gyrocompass-test --vary NAME=V1,V2,...`: the variation studies of report 001
section 1 ("this method can be used to determine the effect of parameter variation (e.g.,
gyro rotor voltage variation) and the effect of gyro input axis azimuth variation on the
gyrocompassing accuracy").

The whole test runs once per setting (its own run directory ``DIR/<name>-<value>``, seed
``seed + k`` for the k-th setting: the same gyro and fixture, a fresh set-up and fresh
noise); a setting's theta is the weighted mean of its two phases' (section 5.4 standard
errors), and theta is fitted against the variable by weighted least squares, the
sensitivity (slope) with its sigma in ``DIR/variation.json``. A setting's sigma adds to
its standard error the error its GSF (eq. 14, common to every run of the test) makes in
theta: theta * sigma(I1 - I1') / (I1 - I1'). The
simulator's sensitivity is the same fit of its noise-free theta at each setting
(``CigtfWorld.exact_theta_arcsec``).

* ``rotor-voltage``: the spin motor's excitation, volts, set by the procedure through the
  gyro power supply's ``VOLT`` command before turn-on (``TestPlan.rotor_voltage_v``, so
  the study runs against a served rack too; the truth takes ``rotor_voltage_v``). In the
  Appendix I model nothing of the gyro survives the four-orientation sum but b D_I and
  c D_OS; the report names no mechanism for a voltage sensitivity. The simulator's is a
  magnetic drift: the spin motor's stray moment, proportional to its excitation, in the
  Earth's field, whose component along I survives the sum (sim/cigtf/sdf_gyro.py;
  ``magnetic_drift_deg_hr_per_gauss``, 0 by default: then the sensitivity is zero).
* ``azimuth``: orientation 1's vertical null, whole degrees (``TestPlan.azimuth_deg``):
  theta follows the input axis's azimuth at -3600 arcsec/deg, and
  ``error_sensitivity`` = slope + 3600 is what the method adds to it (the GSF's linearity).
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from laboratory.record import json_bytes
from procedures.cigtf.procedure import TestPlan
from sim.cigtf.world import CigtfParams, CigtfWorld
from station.config.assignment import named_item
from station.config.cigtf import Eq27Config
from station.config.limits import CigtfLimits
from station.files import write_bytes

VARIABLES = {"rotor-voltage": "V", "azimuth": "deg"}


def parse_vary(text: str) -> tuple[str, list[float]]:
    """``NAME=V1,V2,...`` checked: a known name, at least two distinct finite values
    (whole degrees for the azimuth)."""
    name, values = named_item("--vary", text, VARIABLES,
                              "expected rotor-voltage=V1,V2,... or azimuth=DEG1,DEG2,...")
    try:
        xs = [float(v) for v in values.split(",")]
    except ValueError:
        raise ValueError(f"--vary {text!r}: the values must be numbers") from None
    if len(set(xs)) < 2 or not all(math.isfinite(x) for x in xs):
        raise ValueError(f"--vary {text!r}: at least two distinct finite values")
    if name == "azimuth" and not all(x == int(x) and -45 <= x <= 45 for x in xs):
        raise ValueError(f"--vary {text!r}: azimuths are whole degrees within +-45 "
                         "(the fixture's nulls)")
    if name == "rotor-voltage" and not all(10.0 <= x <= 40.0 for x in xs):
        raise ValueError(f"--vary {text!r}: rotor voltages within 10..40 V")
    return name, xs


def weighted_fit(x: list[float], y: list[float], sigma: list[float]
                 ) -> tuple[float, float, float]:
    """Slope, its sigma and the intercept of the weighted least-squares line."""
    w = 1.0 / np.asarray(sigma) ** 2
    xa, ya = np.asarray(x), np.asarray(y)
    sw, sx, sy = w.sum(), (w * xa).sum(), (w * ya).sum()
    sxx, sxy = (w * xa * xa).sum(), (w * xa * ya).sum()
    det = sw * sxx - sx * sx
    slope = (sw * sxy - sx * sy) / det
    return float(slope), float(math.sqrt(sw / det)), float((sy - slope * sx) / sw)


def gsf_relative_error(run_dir: Path) -> float:
    """sigma(I1 - I1') / (I1 - I1') from the run's step 4.1 currents (eq. 14's GSF)."""
    sheet = json.loads((run_dir / "sheets" / "check_4.1.json").read_text())
    steps = {s["number"]: s["reading"]["currents_ma"] for s in sheet["steps"][:2]}
    a, b = np.asarray(steps["4.1.1"]), np.asarray(steps["4.1.2"])
    diff = a.mean() - b.mean()
    return float(math.sqrt(a.var(ddof=1) / a.size + b.var(ddof=1) / b.size) / abs(diff))


def true_theta(seed: int, p: CigtfParams, azimuth_deg: int) -> float:
    """The simulator's noise-free theta of the run with this seed and params, after its
    set-up (a twin rack set up as the run was) when it had one."""
    from laboratory.cigtf.gyrocompassing import set_up_twin
    from station.racks.cigtf import CigtfRack

    if not p.pretest_setup:
        return CigtfWorld(seed, p).exact_theta_arcsec(azimuth_deg)
    twin = CigtfRack(seed, p)
    with twin:
        set_up_twin(twin)
        return twin.world.exact_theta_arcsec(azimuth_deg)


def run_variation(seed: int, out: Path, name: str, values: list[float],
                  params: CigtfParams | None = None, limits: CigtfLimits | None = None,
                  eq27: Eq27Config | None = None) -> dict:
    """The test at every setting, the fit and its truth; written to ``out/variation.json``."""
    from laboratory.cigtf.gyrocompassing import run_gyrocompass_test

    params = params or CigtfParams()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    settings: list[dict] = []
    xs: list[float] = []
    ys: list[float] = []
    sds: list[float] = []
    truths: list[float] = []
    for k, v in enumerate(values):
        plan = TestPlan(pretest_setup=params.pretest_setup)
        if name == "rotor-voltage":  # set through the power supply (VOLT), not the params
            plan = replace(plan, rotor_voltage_v=v)
        else:
            plan = replace(plan, azimuth_deg=int(v))
        d = out / f"{name}-{v:g}"
        res = run_gyrocompass_test(seed + k, d, params=params, plan=plan, limits=limits,
                                   eq27=eq27)
        rel = gsf_relative_error(d)
        # the simulator's truth of the same voltage, configured in its params
        p = params if plan.rotor_voltage_v is None else replace(
            params, rotor_voltage_v=plan.rotor_voltage_v)
        truth = true_theta(seed + k, p, plan.azimuth_deg)
        conclusions = json.loads((d / "sheets" / "gyrocompass_conclusions.json").read_text())
        phases = [(ph["phase"], ph["theta_arcsec"],
                   conclusions[ph["phase"]]["standard_error_arcsec"]) for ph in res["phases"]]
        w = [1.0 / se**2 for _, _, se in phases]
        theta = sum(wi * t for wi, (_, t, _) in zip(w, phases, strict=True)) / sum(w)
        se = 1.0 / math.sqrt(sum(w))
        sd = math.hypot(se, theta * rel)  # the GSF's error is common to both phases
        xs.append(v)
        ys.append(theta)
        sds.append(sd)
        truths.append(truth)
        settings.append({"value": v, "seed": seed + k, "run_dir": d.name,
                         "phases": {ph: {"theta_arcsec": t, "standard_error_arcsec": e}
                                    for ph, t, e in phases},
                         "theta_arcsec": theta, "sigma_arcsec": sd,
                         "standard_error_arcsec": se, "gsf_relative_error": rel,
                         "truth_arcsec": truth})
    slope, sigma, intercept = weighted_fit(xs, ys, sds)
    t_slope, _, t_intercept = weighted_fit(xs, truths, sds)
    units = f"arcsec/{VARIABLES[name]}"
    truth_fit = {"sensitivity": t_slope, "intercept_arcsec": t_intercept}
    result = {"variable": name, "units": units, "values": values, "seed": seed,
              "settings": settings,
              "sensitivity": slope, "sigma": sigma, "intercept_arcsec": intercept,
              "truth": truth_fit,
              "z": (slope - t_slope) / sigma}
    if name == "azimuth":
        result["error_sensitivity"] = slope + 3600.0
        truth_fit["error_sensitivity"] = t_slope + 3600.0
    write_variation(out, result)
    return result


def write_variation(out: Path, result: dict) -> None:
    """``out/variation.json``, atomically (station.files): a write that fails or is killed
    leaves the study's earlier file whole, never a truncated one."""
    write_bytes(out / "variation.json", json_bytes(result) + b"\n")
