"""II-1.2 (Chart II-7): gyro scale-factor nonlinearity from several table speeds.

Each gyro's input axis is put along the horizontal rotary axis (positions 1, 3, 5); at each
speed counters 1 and k+1 count clock ticks and gyro pulses over whole turns. Fitting the
output frequency P' against the total rate w, P' = a0 + a1 w + a2 w^2, gives the scale
factor at zero rate (1/a1 with the input axis along the rotary axis) and
Q_II = a2 / a1 (Chart IV-2: the (w.G)^2 term). Rates in deg/hr, P' in pulses/s.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, TypedDict

import numpy as np
from numpy.typing import ArrayLike

from procedures.isu.common import (
    check_repeated_counts,
    check_turns_clock,
    patch,
    patch_check_counter,
    rotary_axis_turning,
    run_counters,
    set_modes,
    set_position,
)
from procedures.isu.gyro_rotating import wait_clear_of_pulse
from procedures.isu.plan import DayPlan
from procedures.isu.readings import axis_rate
from procedures.isu.settings import ALONG_AXIS_CHECK, GYRO_ROTATING, turning_repeats, wiring
from procedures.isu.sheets import (
    NonlinearityCounterOutputs,
    NonlinearityCounterSettings,
    NonlinearityGate,
    NonlinearityOutput,
    ResolverSettings,
)
from procedures.runner import CheckSheetRun, Run

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

TITLE = "Gyro scale-factor nonlinearity experiments"
POSITION_OF_GYRO = {1: 1, 2: 3, 3: 5}


def speed_series(st: IsuDrivers, sheet: CheckSheetRun, tag: str, k: int, plan: DayPlan, s1: float,
                 omega_sin_lambda: float) -> list[dict]:
    """Steps 6-10 at every speed of the plan for gyro k (counters 1 and k + 1)."""
    ppr = plan.rotation_pulses_per_rev
    n_pulses = plan.nonlinearity_turns * ppr
    s_phi = 360.0 / ppr
    rows = []
    for rate in plan.nonlinearity_rates_deg_s:
        rtag = f"{tag}/{rate:+g}"
        timeout = 2.0 * plan.nonlinearity_turns * 360.0 / abs(rate) + 60.0
        with sheet.step("6" + rtag, f"Set the turn count on counters 1 and {k + 1}") as s:
            s.reading = {"preset": n_pulses}
        with sheet.step("7" + rtag, f"Run the table at {rate:+g} deg/s") as s:
            st.table.rotate(2, rate)
            st.table.wait_still()
            s.reading = {"rate_deg_s": axis_rate(st, 2, rate)}
        with sheet.step("8" + rtag, "Switch counters to operate between rotary pulses"):
            wait_clear_of_pulse(st, rate, ppr)
            repeats = turning_repeats(k)
            gate = run_counters(st, {c: n_pulses for c in (1, k + 1, *repeats)}, timeout,
                                rotary_axis_turning(st, rate))
            check_repeated_counts(st, gate, repeats, None)
            check_turns_clock(st, 1, gate.readings[1], n_pulses, s1, s_phi, rate)
        with sheet.step("10" + rtag, "Record the outputs") as s:
            ticks, counts = gate.readings[1], gate.readings[k + 1]
            t = ticks * s1
            # Chart II-7 step 14: the total rate about the rotary axis. With phi1 = 90 the
            # axis R1 points south (Chart I-4), so the Earth adds -W sin(lambda); the
            # chart's "+" assumes the opposite sense of the axis.
            w_table = math.copysign(s_phi * n_pulses / t * 3600.0, rate)
            row = {"rate_deg_s": rate, "ticks": ticks, "counts": counts,
                   "w_deg_hr": w_table - omega_sin_lambda, "p_dot": counts / t}
            rows.append(row)
            s.reading = row
    return rows


def speed_key(rate: float) -> str:
    """A speed as the nonlinearity sheets (Charts II-8, II-9) key it: signed deg/s."""
    return f"{rate:+g}"


def nonlinearity_settings(plan: DayPlan) -> NonlinearityCounterSettings:
    """Chart II-8 from the plan: per gyro and speed, counters 1 and k + 1 preset to the
    rotary-axis pulses of the plan's whole turns (Chart II-7 step 6)."""
    preset = plan.nonlinearity_turns * plan.rotation_pulses_per_rev
    return NonlinearityCounterSettings(gyros={
        str(k): {speed_key(r): NonlinearityGate(counters=(1, k + 1), preset=preset,
                                                rate_deg_s=r)
                 for r in plan.nonlinearity_rates_deg_s}
        for k in (1, 2, 3)})


def nonlinearity_outputs(points: dict[int, list[dict]]) -> NonlinearityCounterOutputs:
    """Chart II-9 from the series: counter outputs (step 10) and the rates of steps 14-15."""
    return NonlinearityCounterOutputs(gyros={
        str(k): {speed_key(r["rate_deg_s"]): NonlinearityOutput(
            ticks=r["ticks"], counts=r["counts"], w_deg_hr=r["w_deg_hr"], p_dot=r["p_dot"])
            for r in rows}
        for k, rows in points.items()})


def nonlinearity_experiment(st: IsuDrivers, run: Run, settings: ResolverSettings, plan: DayPlan,
                            s1: float, omega_sin_lambda: float) -> dict[int, list[dict]]:
    """Chart II-7 steps 1-15; returns per gyro the (w, P', counts, ticks) points. The
    settings go on Chart II-8 before the runs, the outputs on Chart II-9 after them."""
    points: dict[int, list[dict]] = {}
    with run.sheet("II-7", TITLE) as sheet:
        with sheet.step("1", "Resolver settings and the nonlinearity Counter Settings Sheet "
                        "(Chart II-8) available") as s:
            run.save_sheet("nonlinearity_counter_settings", nonlinearity_settings(plan))
            s.reading = {"sheet": "nonlinearity_counter_settings"}
        sheet.done("2", "Turn-on procedures complete (Chart I-1)")
        with sheet.step("3", "Patch gyros, master oscillator and rotary output (positions 1-6)"):
            patch(st, wiring(GYRO_ROTATING))
        with sheet.step("4", "Set counters to measure Z"):
            set_modes(st, (1, 2, 3, 4, 5, 6), "measure Z")
        for k in (1, 2, 3):
            m = POSITION_OF_GYRO[k]
            p = settings.positions[str(m)]
            tag = f"/g{k}"
            with sheet.step("5" + tag, f"Set phi1 = 90 deg, phi3 and phi4 of position {m}"):
                set_position(st, 90.0, None, p.phi3, p.phi4, level=False)
                patch_check_counter(st, ALONG_AXIS_CHECK, k)  # counted again on counter 5
            points[k] = speed_series(st, sheet, tag, k, plan, s1, omega_sin_lambda)
            with sheet.step("12" + tag, "Stop the table"):
                st.table.stop(2)
                st.table.wait_still()
        sheet.done("13", "Gyros 2 and 3 done as gyro 1")
        with sheet.step("15", "Record w and P' on the nonlinearity Counter Outputs Sheet "
                        "(Chart II-9)") as s:
            run.save_sheet("nonlinearity_counter_outputs", nonlinearity_outputs(points))
            s.reading = {"sheet": "nonlinearity_counter_outputs"}
    return points


# Q_IS: the report's Chart II-5 lists it under "special experiments" without one. Designed
# here (docs/special-experiments.md): the same speed series with the rotary axis along the
# bisector of the gyro's input and spin axes, (G + S)/sqrt2, where (w.G)(w.S) = w^2/2.
NOMINAL_GS = {
    1: ((1.0, 0.0, 0.0), (0.0, -1.0, 0.0)),
    2: ((0.0, 1.0, 0.0), (0.0, 0.0, -1.0)),
    3: ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
}
Q_IS_TITLE = "Q_IS experiment (designed): speed series along the input-spin bisector"


def bisector(k: int) -> np.ndarray:
    g, s = (np.array(v) for v in NOMINAL_GS[k])
    return (g + s) / math.sqrt(2.0)


def q_is_experiment(st: IsuDrivers, run: Run, t_bi: ArrayLike, plan: DayPlan, s1: float,
                    omega_sin_lambda: float) -> dict[int, list[dict]]:
    from procedures.isu.survey_math import settings_for

    points: dict[int, list[dict]] = {}
    with run.sheet("II-7Q", Q_IS_TITLE) as sheet:
        with sheet.step("1", "Patch as for positions 1-6; counters to measure Z"):
            patch(st, wiring(GYRO_ROTATING))
            set_modes(st, (1, 2, 3, 4, 5, 6), "measure Z")
        for k in (1, 2, 3):
            tag = f"/g{k}"
            phi3, phi4 = settings_for(np.asarray(t_bi), bisector(k))
            with sheet.step("5" + tag, f"Set phi1 = 90 deg; (G{k} + S{k})/sqrt2 along the "
                            "rotary axis") as s:
                set_position(st, 90.0, None, phi3, phi4, level=False)
                patch_check_counter(st, ALONG_AXIS_CHECK, k)  # counted again on counter 5
                s.reading = {"phi3": phi3, "phi4": phi4}
            points[k] = speed_series(st, sheet, tag, k, plan, s1, omega_sin_lambda)
            with sheet.step("12" + tag, "Stop the table"):
                st.table.stop(2)
                st.table.wait_still()
    return points


def _along(r: np.ndarray, g_body: np.ndarray, k: int) -> tuple[float, float]:
    """(r.G, r.S) for a rotary axis r in the plane of gyro k's nominal G and S: G is the
    calibrated input axis; S, normal to it, differs from its nominal along G_nom by -G.S_nom
    (first order; its turn about G, along O, does not reach r)."""
    g_nom, s_nom = (np.array(v) for v in NOMINAL_GS[k])
    return float(r @ g_body), float(r @ s_nom) - float(g_body @ s_nom) * float(r @ g_nom)


def q_is_from_fit(a2_over_a1: float, sigma_ratio: float, q_ii: float, sigma_q_ii: float,
                  g_body: np.ndarray, k: int) -> tuple[float, float]:
    """Q_IS from the bisector fit alone, Q_II given (another sheet's): a2/a1 = Q_II (r.G)
    + Q_IS (r.S), r the bisector."""
    rg, rs = _along(bisector(k), g_body, k)
    q = (a2_over_a1 - q_ii * rg) / rs
    sig = math.hypot(sigma_ratio, sigma_q_ii * rg) / abs(rs)
    return q, sig


def q_terms(along_g: tuple[float, float], along_bisector: tuple[float, float],
            g_body: np.ndarray, k: int) -> tuple[tuple[float, float], tuple[float, float]]:
    """((Q_II, sigma), (Q_IS, sigma)) from both series' (a2/a1, sigma): Chart II-7's, whose
    rotary axis is the nominal G, and II-7Q's along the bisector. Each ratio is Q_II (r.G) +
    Q_IS (r.S). Along the nominal G, r.S is the input axis' tilt towards the spin axis
    (-G.S_nom, up to 1e-3 at the admitted misalignments), which the print's Q_II = a2/a1
    leaves out: with Q_IS at its bound (1e-7 hr/deg) that put Q_II 8-13 sigma off."""
    g7, s7 = _along(np.array(NOMINAL_GS[k][0]), g_body, k)
    gq, sq = _along(bisector(k), g_body, k)
    (a7, sa7), (aq, saq) = along_g, along_bisector
    det = g7 * sq - s7 * gq
    q_ii = (a7 * sq - aq * s7) / det
    q_is = (g7 * aq - gq * a7) / det
    return ((q_ii, math.hypot(sq * sa7, s7 * saq) / abs(det)),
            (q_is, math.hypot(g7 * saq, gq * sa7) / abs(det)))


class NonlinearityFit(TypedDict):
    """The quadratic P' = a0 + a1 w + a2 w^2 of one speed series and its checks."""

    a0: float
    a1: float
    a2: float
    Q_II: float  # a2 / a1, hr/deg
    sigma: float  # of Q_II
    scale_factor_arcsec: float  # 1 / a1
    residual_z: list[float]  # each speed off the quadratic through the others, in sigma


def fit_nonlinearity(rows: list[dict], sigma_counts: float | np.ndarray) -> NonlinearityFit:
    """Chart II-7 steps 16-17: weighted quadratic fit of P' against w; Q_II and its sigma.

    sigma_counts: standard error of one count (quantization and noise), pulses; one for all
    speeds or one per speed.
    """
    w = np.array([r["w_deg_hr"] for r in rows])
    p = np.array([r["p_dot"] for r in rows])
    gate_s = np.array([r["counts"] / r["p_dot"] for r in rows])
    sig = sigma_counts / gate_s
    scale = 1e4  # deg/hr: keep the design matrix well conditioned
    x = w / scale
    a = np.stack([np.ones_like(x), x, x * x], axis=1) / sig[:, None]
    coef, *_ = np.linalg.lstsq(a, p / sig, rcond=None)
    cov = np.linalg.inv(a.T @ a)
    a0, a1, a2 = coef[0], coef[1] / scale, coef[2] / scale**2
    q = a2 / a1
    # d q / d(a1, a2) in the scaled coefficients
    jac = np.array([0.0, -coef[2] / coef[1] ** 2 / scale, 1.0 / coef[1] / scale])
    sq = float(np.sqrt(jac @ cov @ jac))
    # each speed's residual over its own sigma (the fit's leverage removed): a garbled count
    # stands out of the quadratic, the fit has len(rows) - 3 degrees of freedom
    r = p / sig - a @ coef
    lev = np.einsum("ij,jk,ik->i", a, cov, a)
    z = r / np.sqrt(np.maximum(1.0 - lev, 1e-12))
    # P' = a1 w: 1/a1 deg/hr per pulse/s = 1/a1 arcsec per pulse
    return {"a0": float(a0), "a1": float(a1), "a2": float(a2), "Q_II": float(q), "sigma": sq,
            "scale_factor_arcsec": 1.0 / float(a1), "residual_z": [float(x) for x in z]}
