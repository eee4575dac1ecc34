"""II-1.2 (Chart II-7): gyro scale-factor nonlinearity from several table speeds.

Each gyro's input axis is put along the horizontal rotary axis (positions 1, 3, 5); at each
speed counters 1 and k+1 count clock ticks and gyro pulses over whole turns. Fitting the
output frequency P' against the total rate w, P' = a0 + a1 w + a2 w^2, gives the scale
factor at zero rate (1/a1 with the input axis along the rotary axis) and
Q_II = a2 / a1 (Chart IV-2: the (w.G)^2 term). Rates in deg/hr, P' in pulses/s.
"""

from __future__ import annotations

import math

import numpy as np

from procedures.common import patch, run_counters, set_modes, set_position
from procedures.gyro_rotating import wait_clear_of_pulse
from procedures.plan import DayPlan
from procedures.runner import Run
from procedures.settings import GYRO_ROTATING, wiring
from procedures.sheets import ResolverSettings

TITLE = "Gyro scale-factor nonlinearity experiments"
POSITION_OF_GYRO = {1: 1, 2: 3, 3: 5}


def nonlinearity_experiment(st, run: Run, settings: ResolverSettings, plan: DayPlan,
                            s1: float, omega_sin_lambda: float) -> dict[int, list[dict]]:
    """Chart II-7 steps 1-15; returns per gyro the (w, P', counts, ticks) points."""
    ppr = plan.rotation_pulses_per_rev
    n_pulses = plan.nonlinearity_turns * ppr
    s_phi = 360.0 / ppr
    points: dict[int, list[dict]] = {}
    with run.sheet("II-7", TITLE) as sheet:
        sheet.done("1", "Resolver and counter settings available")
        sheet.done("2", "Turn-on procedures complete (Chart I-1)")
        with sheet.step("3", "Patch gyros, master oscillator and rotary output (positions 1-6)"):
            patch(st, wiring(GYRO_ROTATING))
        with sheet.step("4", "Set counters to measure Z"):
            set_modes(st, (1, 2, 3, 4), "measure Z")
        for k in (1, 2, 3):
            m = POSITION_OF_GYRO[k]
            p = settings.positions[str(m)]
            tag = f"/g{k}"
            with sheet.step("5" + tag, f"Set phi1 = 90 deg, phi3 and phi4 of position {m}"):
                set_position(st, 90.0, None, p.phi3, p.phi4, level=False)
            rows = []
            for rate in plan.nonlinearity_rates_deg_s:
                rtag = f"{tag}/{rate:+g}"
                timeout = 2.0 * plan.nonlinearity_turns * 360.0 / abs(rate) + 60.0
                with sheet.step("6" + rtag, "Set the turn count on counters 1 and "
                                f"{k + 1}") as s:
                    s.reading = {"preset": n_pulses}
                with sheet.step("7" + rtag, f"Run the table at {rate:+g} deg/s") as s:
                    st.table.rotate(2, rate)
                    st.table.wait_still()
                    s.reading = {"rate_deg_s": st.table.rate(2)}
                with sheet.step("8" + rtag, "Switch counters to operate between rotary pulses"):
                    wait_clear_of_pulse(st, rate, ppr)
                    gate = run_counters(st, {1: n_pulses, k + 1: n_pulses}, timeout)
                with sheet.step("10" + rtag, "Record the outputs") as s:
                    ticks, counts = gate.readings[1], gate.readings[k + 1]
                    t = ticks * s1
                    # Chart II-7 step 14: the total rate about the rotary axis. With phi1 = 90
                    # the axis R1 points south (Chart I-4), so the Earth adds -W sin(lambda);
                    # the chart's "+" assumes the opposite sense of the axis.
                    w_table = math.copysign(s_phi * n_pulses / t * 3600.0, rate)
                    row = {"rate_deg_s": rate, "ticks": ticks, "counts": counts,
                           "w_deg_hr": w_table - omega_sin_lambda, "p_dot": counts / t}
                    rows.append(row)
                    s.reading = row
            with sheet.step("12" + tag, "Stop the table"):
                st.table.stop(2)
                st.table.wait_still()
            points[k] = rows
        sheet.done("13", "Gyros 2 and 3 done as gyro 1")
    return points


def fit_nonlinearity(rows: list[dict], sigma_counts: float) -> dict[str, float]:
    """Chart II-7 steps 16-17: weighted quadratic fit of P' against w; Q_II and its sigma.

    sigma_counts: standard error of one count (quantization and noise), pulses.
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
    # P' = a1 w: 1/a1 deg/hr per pulse/s = 1/a1 arcsec per pulse
    return {"a0": float(a0), "a1": float(a1), "a2": float(a2), "Q_II": float(q), "sigma": sq,
            "scale_factor_arcsec": 1.0 / float(a1)}
