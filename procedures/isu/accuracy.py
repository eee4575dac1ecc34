"""II-6.2: collection times from required accuracies (Charts II-18..II-24 by prediction).

Before anything is measured, a nominal day (instruments at their class's nominal constants,
the table at the Chart I-5 settings of the unit's mounting T^BI, the day's order of positions
with the gate times under trial) is reduced and propagated exactly as Chart II-15 step 8
propagates a measured day (procedures.isu.calibration.compute: J Sigma_z J^T with the lab's
NoiseSpec). That gives each required accuracy's predicted sigma against the collection time
of the gate it concerns; ``choose_times`` takes the smallest time meeting the requirement,
never below the manual's default, and refuses what no gate up to the maximum reaches.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from procedures.isu import survey_math as sm
from procedures.isu.calibration import (
    AccelPosition,
    CalibrationData,
    Constants,
    GyroPosition,
    NoiseSpec,
)
from procedures.isu.calibration.compute import data_covariance, estimate, estimator_jacobian
from procedures.isu.calibration.forward import (
    GYRO_TERMS,
    NOMINAL_AXES,
    AccelModel,
    GyroModel,
)
from procedures.isu.calibration.geometry import (
    DEFAULT_PHI0_DEG,
    FIRST_COLUMN,
    chart_i5_settings,
    t_br,
)
from procedures.isu.calibration.inputs import TableGeometry
from procedures.isu.calibration.reduce import reduce
from procedures.isu.site import Site

# The day's timeline as a default day runs it (station day, seed 0): the first turning gate
# opens after turn-on and the survey, each position adds about 23 s of setting and
# settling, the special experiments (II-7, II-7Q, II-10) sit between positions 6 and 7, and
# the bubbles are read 2.5 s before an accelerometer gate. Only the correlated noises (drift,
# pier tilt) see these instants.
FIRST_GATE_S = 1976.0
POSITION_GAP_S = 23.0
SPECIAL_EXPERIMENTS_S = 8389.0
LEVEL_LEAD_S = 2.5
SURVEY_S = 1000.0  # without level corrections the tilt counts from the survey's level reading
# Positions 1-6 as the default day runs them at any number of turns (station day --only II-6,
# min_turns 1..10, seeds 1 and 2: the same instants): the first gate opens on the rotation
# pulse 17.5 s after the switch to operate, and a gate ends 46 s before the next opens (37 s
# from position 2 to 3), not the nominal 23 s. Drift and pier tilt (the 60 s wobble) see the
# pair's spacing; the static positions keep the nominal timeline (``Lab.turning_first_s``).
DAY_TURNING_FIRST_S = 1993.5
DAY_TURNING_GAPS_S = (46.0, 36.9, 46.0, 46.0, 46.0)

GATES = ("gyro 1-6", "gyro 7-15", "accel vertical", "accel horizontal")
GATE_OF = {  # requirement -> the gate whose collection time it sets (II-6.2)
    "gyro_scale_factor": "gyro 1-6",
    "gyro_drift_deg_hr": "gyro 7-15",
    "accel_scale_factor_ppm": "accel vertical",
    "accel_bias_micro_g": "accel horizontal",
}
GATE_UNITS = {"gyro 1-6": "turns", "gyro 7-15": "s", "accel vertical": "s",
              "accel horizontal": "s"}


class Unreachable(ValueError):
    """A required accuracy that no admissible gate reaches (an error of use: nothing runs)."""


@dataclass(frozen=True)
class Times:
    """The day's collection times: whole turns in positions 1-6, seconds of gate elsewhere."""

    turns: int = 10
    gyro_s: float = 600.0
    accel_vertical_s: float = 600.0
    accel_horizontal_s: float = 1800.0

    def get(self, gate: str) -> float:
        return float(getattr(self, _FIELD[gate]))

    def set(self, gate: str, value: float) -> Times:
        if gate == "gyro 1-6":
            return replace(self, turns=int(value))
        return replace(self, **{_FIELD[gate]: float(value)})  # type: ignore[arg-type]


_FIELD = dict(zip(GATES, ("turns", "gyro_s", "accel_vertical_s", "accel_horizontal_s"),
                  strict=True))


Matrix3 = tuple[tuple[float, float, float], tuple[float, float, float],
                tuple[float, float, float]]
SQUARE: Matrix3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


@dataclass(frozen=True)
class Lab:
    """What the prediction knows of the station: site, noise, counter clock, table, the
    unit's mounting T^BI, and the instruments' class (3 arcsec/pulse gyros, 2000
    (pulses/s)/g accelerometers).

    The mounting matters through the sense of its small bolting error: B1 lies nearly along
    I1 in position 1, so Chart I-5's phi4 there (and so which of the horizontal
    accelerometers of positions 7/8 takes phi3's setting error, and how the second column
    of T^BR turns) is set by that error's direction, not by the nominal square bolting
    (where phi4 is arbitrary, taken 0)."""

    site: Site
    noise: NoiseSpec
    s1: float = 1e-6
    f0: float = 20000.0
    table_rate_deg_s: float = 15.0
    pulses_per_rev: int = 1
    dphi_arcsec: float = 3.0
    d1: float = 2000.0
    t_bi: Matrix3 = SQUARE
    # positions 1-6's first gate opening and the gaps between their gates (s); the nominal
    # timeline by default, ``DAY_TURNING_*`` for the day's (station plan --verify)
    turning_first_s: float = FIRST_GATE_S
    turning_gaps_s: tuple[float, ...] = (POSITION_GAP_S,) * 5

    def geometry(self) -> TableGeometry:
        """The table geometry of a day on this mounting: Chart I-5 settings, position 0."""
        s = chart_i5_settings(np.array(self.t_bi))
        return TableGeometry(
            t_bi=self.t_bi, phi0_deg=DEFAULT_PHI0_DEG,
            settings_deg={m: (math.degrees(a), math.degrees(b)) for m, (a, b) in s.items()})

    def turn_s(self) -> float:
        """Seconds of one whole turn."""
        return 360.0 / self.table_rate_deg_s


def planning_mounting(t_bi: object | None) -> Matrix3:
    """T^BI as a planning figure: to 1e-4 (20 arcsec), squared up, so that the day's check
    before the run (the station's mounting) and II-6 (the survey's) ask the same and share
    one answer; the prediction needs the mounting only to a fraction of a degree."""
    if t_bi is None:
        return SQUARE
    m = np.round(np.asarray(t_bi, dtype=float), 4)
    u, _, vt = np.linalg.svd(m)
    r = np.round(u @ vt, 12) + 0.0
    return tuple(tuple(float(x) for x in row) for row in r)  # type: ignore[return-value]


def _constants(lab: Lab, geo: TableGeometry) -> Constants:
    cols = {m: sm.t_br_column2(np.array(geo.t_bi), *geo.settings_deg[m])
            for m in (1, 3, 5, 13, 14, 15)}
    return Constants(g=lab.site.g, w_sin_lambda=lab.site.omega_sin_lambda,
                     w_cos_lambda=lab.site.omega_cos_lambda, s1_t=lab.s1,
                     s_phi=360.0 / lab.pulses_per_rev, t_br_column2=cols)


def nominal_data(times: Times, lab: Lab, level: bool = True) -> CalibrationData:
    """The counter data a nominal unit gives over a day with these times (no noise)."""
    geo = lab.geometry()
    c = _constants(lab, geo)
    dphi = lab.dphi_arcsec / 3600.0
    gyros = [GyroModel(dphi, g.copy(), o.copy(), s.copy(), dict.fromkeys(GYRO_TERMS, 0.0))
             for g, o, s in NOMINAL_AXES]
    accels = [AccelModel(lab.d1, np.eye(3)[k].copy(), 0.0, 0.0, 0.0) for k in range(3)]
    gyro: dict[int, GyroPosition] = {}
    T = times.turns * lab.turn_s()
    t = lab.turning_first_s
    for m in range(1, 7):
        delta = tuple(g.turning_rate(FIRST_COLUMN[m], lab.table_rate_deg_s, c) * T
                      for g in gyros)
        gyro[m] = GyroPosition(n1=T / lab.s1, n_phi=times.turns * lab.pulses_per_rev,
                               delta=delta, t0=t, t1=t + T)
        t += T + (lab.turning_gaps_s[m - 1] if m < 6 else 0.0)
    t = FIRST_GATE_S  # the static positions keep the nominal timeline (summed as it was)
    for _ in range(6):
        t += T + POSITION_GAP_S
    t += SPECIAL_EXPERIMENTS_S
    for m in range(7, 16):
        frame = t_br(m, c)
        delta = tuple(g.static_rate(frame[:, 0], frame[:, 1], c) * times.gyro_s for g in gyros)
        gyro[m] = GyroPosition(n1=times.gyro_s / lab.s1, delta=delta, t0=t,
                               t1=t + times.gyro_s)
        t += times.gyro_s + POSITION_GAP_S
    accel: dict[int, AccelPosition] = {}
    for m in range(7, 15):
        up = t_br(m, c)[:, 0]
        gamma, n1 = {}, {}
        longest = 0.0
        for k, am in enumerate(accels, start=1):
            vertical = m in (2 * k + 5, 2 * k + 6)
            preset = math.ceil((times.accel_vertical_s if vertical
                                else times.accel_horizontal_s) * lab.f0)
            f_diff = am.difference(up, c)
            for ell, f in ((1, lab.f0 - 0.5 * f_diff), (2, lab.f0 + 0.5 * f_diff)):
                gamma[(k, ell)] = float(preset)
                n1[(k, ell)] = preset / (f * lab.s1)
                longest = max(longest, preset / f)
        accel[m] = AccelPosition(gamma=gamma, n1=n1, t0=t, t1=t + longest,
                                 t_level=t - LEVEL_LEAD_S if level else SURVEY_S)
        t += longest + POSITION_GAP_S
    return CalibrationData(constants=c, gyro=gyro, accel=accel, geometry=geo)


Row = tuple[str, str]


class Predictor:
    """Predicted covariance of the Chart II-5 constants against the day's collection times.

    The estimator's Jacobian is taken once at the default times (the nominal rates do not
    depend on the times); each trial rebuilds only the data covariance."""

    def __init__(self, lab: Lab, default: Times | None = None) -> None:
        self.lab = lab
        self.default = default or Times()
        self._cache: dict[tuple[Times, bool], np.ndarray] = {}
        data = nominal_data(self.default, lab)
        red = reduce(data)
        self.keys = list(red.values)
        self.est = estimate(red.values, data.constants)
        self.rows = [r for r, v in self.est.items() if v is not None]
        self.index = {r: i for i, r in enumerate(self.rows)}
        cov = data_covariance(red, self.keys, data, lab.noise, self.est)
        z0 = np.array([red.values[k] for k in self.keys])
        steps = np.sqrt(np.maximum(np.diag(cov), 0.0))
        steps = np.where(steps > 0, steps, 1e-9 * np.maximum(np.abs(z0), 1.0))
        # the nominal unit has no drift coefficients, so the terms the printed gyro forms
        # neglect vanish and their correction (three passes of the forms) changes this
        # Jacobian by rounding only (1e-15 relative): the printed forms alone (issue 17)
        jac = estimator_jacobian(red.values, data.constants, self.keys, self.rows, steps,
                                 corrected=False)
        self.jac = jac
        self._cache[(self.default, True)] = jac @ cov @ jac.T  # what _covariance would give

    def covariance(self, times: Times, level: bool = True) -> np.ndarray:
        """J Sigma_z J^T of the constants for a day with these times (each evaluated once:
        the search asks for the default times once per gate)."""
        key = (times, level)
        if key not in self._cache:
            self._cache[key] = self._covariance(times, level)
        return self._cache[key]

    def _covariance(self, times: Times, level: bool) -> np.ndarray:
        data = nominal_data(times, self.lab, level)
        red = reduce(data)
        if list(red.values) != self.keys:
            raise ValueError("the nominal day's data changed shape with the times")
        cov = data_covariance(red, self.keys, data, self.lab.noise, self.est)
        return self.jac @ cov @ self.jac.T

    def sigma(self, cov: np.ndarray, inst: str, par: str) -> float:
        i = self.index[(inst, par)]
        return float(math.sqrt(max(cov[i, i], 0.0)))

    def quantities(self, cov: np.ndarray) -> dict[str, float]:
        """The charts' quantities (each the largest over the three instruments), in the
        requirements' units."""
        g = self.lab.site.g
        s = self.sigma
        out = {
            "gyro_scale_factor": max(s(cov, f"gyro{k}", "DeltaPhi")
                                     / float(self.est[(f"gyro{k}", "DeltaPhi")] or 1.0)
                                     for k in (1, 2, 3)),
            "gyro R": max(s(cov, f"gyro{k}", "R") for k in (1, 2, 3)),
            "gyro B g": g * max(s(cov, f"gyro{k}", p) for k in (1, 2, 3)
                                for p in ("B_I", "B_O", "B_S")),
            "gyro C g^2": g * g * max(s(cov, f"gyro{k}", p) for k in (1, 2, 3)
                                      for p in ("C_II", "C_SS")),
            "accel_scale_factor_ppm": 1e6 * max(self.vertical_sigma(cov, k)
                                                for k in (1, 2, 3)),
            "accel_bias_micro_g": 1e6 * max(s(cov, f"accel{k}", "D0") for k in (1, 2, 3)),
            "accel misalignment ppm": 1e6 * max(s(cov, f"accel{k}", f"A.B{j}")
                                                for k in (1, 2, 3) for j in (1, 2, 3)
                                                if j != k),
        }
        out["gyro_drift_deg_hr"] = max(out["gyro R"], out["gyro B g"], out["gyro C g^2"])
        return out

    def vertical_sigma(self, cov: np.ndarray, k: int) -> float:
        """Relative sigma of accelerometer k's vertical combination D1 (A.B_k) + g^2 D1 D3
        (what positions 2k+5, 2k+6 measure, Chart II-21), linearised over the rows."""
        g2 = self.lab.site.g ** 2
        a = f"accel{k}"
        d1 = float(self.est[(a, "D1")] or 0.0)
        ab = float(self.est[(a, f"A.B{k}")] or 0.0)
        d3 = float(self.est[(a, "D3")] or 0.0)
        grad = np.zeros(len(self.rows))
        grad[self.index[(a, "D1")]] = ab + g2 * d3
        grad[self.index[(a, f"A.B{k}")]] = d1
        grad[self.index[(a, "D3")]] = g2 * d1
        value = d1 * (ab + g2 * d3)
        return float(math.sqrt(max(grad @ cov @ grad, 0.0))) / abs(value)


@dataclass(frozen=True)
class GateChoice:
    """One gate of the Counter Settings Sheet: why its time is what it is."""

    gate: str
    units: str
    default: float
    chosen: float
    requirement: str
    required: float
    predicted: float  # the requirement's predicted sigma at the chosen time
    why: str


def _longest(gate: str, lab: Lab, max_gate_s: float) -> float:
    if gate == "gyro 1-6":
        return float(math.floor(max_gate_s / lab.turn_s() + 1e-9))
    return float(math.floor(max_gate_s))


def _clock_floor(lab: Lab, times: Times, name: str, req: float) -> str:
    """What to add to an unreachable requirement's message when the master oscillator's
    offset (``NoiseSpec.oscillator_frequency_error``) is what keeps the longest gate
    (``times``) from it."""
    e = lab.noise.oscillator_frequency_error
    if not e:
        return ""
    still = replace(lab, noise=lab.noise.model_copy(update={"oscillator_frequency_error": 0.0}))
    pred = Predictor(still, times)
    if pred.quantities(pred.covariance(times))[name] > req:
        return ""
    return (f"; the master oscillator's offset allowed for, {e:.3g} ([oscillator] "
            "frequency_error), keeps every gate from it")


def choose_times(required: dict[str, float], max_gate_s: float, lab: Lab,
                 default: Times | None = None, predictor: Predictor | None = None,
                 fixed: dict[str, float] | None = None) -> tuple[Times, list[GateChoice]]:
    """Each gate's time: the manual's default when the prediction meets its requirement
    there, else the smallest whole second (turn) that meets it; Unreachable (naming the
    requirement) when even the longest admissible gate does not. A gate in ``fixed`` (a
    study's sweep) takes that time, its requirement not applied."""
    default = default or Times()
    pred = predictor or Predictor(lab, default)
    times = default
    for gate, v in (fixed or {}).items():
        times = times.set(gate, v)
    choices = []
    for name, gate in GATE_OF.items():
        req = required[name]
        units = GATE_UNITS[gate]
        d = default.get(gate)
        hi = _longest(gate, lab, max_gate_s)
        if fixed and gate in fixed:
            v = fixed[gate]
            if not 0 < v <= hi:
                raise Unreachable(f"{gate} fixed at {v:g} {units}: outside the admissible "
                                  f"0..{hi:g} {units} (max_gate_minutes {max_gate_s / 60:g})")
            got = pred.quantities(pred.covariance(times))[name]
            choices.append(GateChoice(gate, units, d, v, name, req, got,
                                      f"fixed at {v:g} {units} for a study ({name} not "
                                      "applied)"))
            continue
        if d > hi:
            raise Unreachable(f"max_gate_minutes {max_gate_s / 60:g}: shorter than the "
                              f"manual's {d:g} {units} for {gate} ({name})")

        def sigma_at(v: float, gate: str = gate, name: str = name, base: Times = times
                     ) -> float:
            return pred.quantities(pred.covariance(base.set(gate, v)))[name]

        at_default = sigma_at(d)
        if at_default <= req:
            chosen, got = d, at_default
            why = f"default: the manual's {d:g} {units} already give {at_default:.3g}"
        else:
            at_max = sigma_at(hi)
            if at_max > req:
                raise Unreachable(
                    f"{name} = {req:g}: no admissible gate reaches it; {gate} predicted "
                    f"{at_default:.3g} at the manual's {d:g} {units} and {at_max:.3g} at the "
                    f"longest, {hi:g} {units} (max_gate_minutes {max_gate_s / 60:g})"
                    + _clock_floor(lab, times.set(gate, hi), name, req))
            lo, got = d, at_max
            while hi - lo > 1:
                mid = float(math.floor((lo + hi) / 2))
                s = sigma_at(mid)
                if s <= req:
                    hi, got = mid, s
                else:
                    lo = mid
            chosen = hi
            why = f"lengthened for {name} = {req:g}"
        times = times.set(gate, chosen)
        choices.append(GateChoice(gate, units, d, chosen, name, req, got, why))
    return times, choices
