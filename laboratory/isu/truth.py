"""Ground truth of the simulated ISU in the units of the Calibration Results Sheet.

Only the station layer may look at the simulator: procedures estimate, this module says
what the right answers were, so results can show estimate, truth and error side by side.

A gyro's B, C, Q_IS and J are given on the axes the calibration defines them on
(``forward.lab_axes``: its measured G, the nominal O squared up to it): no position of
Chart II-5 sees a turn of the true O and S about G, which only relabels those terms among
themselves, and a navigation program compensating on those axes with them is exact. The
relabelling leaves (a.O)^2, (w.G)(w.O) and a J about S unmodelled: second order in the turn,
or first order in Q_IS and J, a hundredth of a sigma at the admissible bounds.
"""

from __future__ import annotations

import numpy as np

from procedures.isu.calibration.forward import lab_axes
from procedures.isu.sheets import ARCSEC_PER_DEG
from sim.isu.unit import Gyro
from sim.isu.world import World

GYRO_UNITS = {
    "DeltaPhi": "deg/pulse", "G.B1": "", "G.B2": "", "G.B3": "", "R": "deg/hr",
    "B_I": "deg/hr/g", "B_O": "deg/hr/g", "B_S": "deg/hr/g", "C_II": "deg/hr/g^2",
    "C_SS": "deg/hr/g^2", "C_IS": "deg/hr/g^2", "C_OS": "deg/hr/g^2", "C_IO": "deg/hr/g^2",
    "Q_II": "hr/deg", "Q_IS": "hr/deg", "J": "hr",
}
ACCEL_UNITS = {
    "D1": "(pulses/s)/g", "A.B1": "", "A.B2": "", "A.B3": "", "D0": "g", "D2": "g/g^2",
    "D3": "g/g^3",
}


def _sym(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The matrix M with a.M.a = (a.x)(a.y)."""
    return 0.5 * (np.outer(x, y) + np.outer(y, x))


def on_lab_axes(k: int, g: Gyro) -> dict[str, float]:
    """Gyro k's axis-dependent Chart IV-2 coefficients (lab units) on the calibration's
    axes: the true model's g-sensitivity vector, compliance and Q matrices and J vector
    read along the lab's G, O, S."""
    p = g.p
    G, O, S = lab_axes(k, g.G)  # noqa: E741
    b = p.B_I_deg_hr_g * g.G + p.B_O_deg_hr_g * g.O + p.B_S_deg_hr_g * g.S
    c = (p.C_II_deg_hr_g2 * np.outer(g.G, g.G) + p.C_SS_deg_hr_g2 * np.outer(g.S, g.S)
         + p.C_IS_deg_hr_g2 * _sym(g.G, g.S) + p.C_OS_deg_hr_g2 * _sym(g.O, g.S)
         + p.C_IO_deg_hr_g2 * _sym(g.G, g.O))
    q = p.Q_II_hr_deg * np.outer(g.G, g.G) + p.Q_IS_hr_deg * _sym(g.G, g.S)
    return {"B_I": float(b @ G), "B_O": float(b @ O), "B_S": float(b @ S),
            "C_II": float(G @ c @ G), "C_SS": float(S @ c @ S), "C_IS": float(2 * G @ c @ S),
            "C_OS": float(2 * O @ c @ S), "C_IO": float(2 * G @ c @ O),
            "Q_II": float(G @ q @ G), "Q_IS": float(2 * G @ q @ S),
            "J": float(p.J_hr * (g.O @ O))}


def calibration_truth(world: World) -> dict[tuple[str, str], float]:
    out: dict[tuple[str, str], float] = {}
    for k, g in enumerate(world.isu.gyros, start=1):
        p = g.p
        inst = f"gyro{k}"
        vals = {
            "DeltaPhi": p.scale_factor_arcsec_per_pulse / ARCSEC_PER_DEG,  # Chart II-5
            "G.B1": float(g.G[0]), "G.B2": float(g.G[1]), "G.B3": float(g.G[2]),
            "R": p.R_deg_hr, **on_lab_axes(k, g),
        }
        out.update({(inst, n): float(v) for n, v in vals.items()})
    for k, a in enumerate(world.isu.accels, start=1):
        ap = a.p
        inst = f"accel{k}"
        vals = {
            "D1": ap.D1_pps_per_g, "A.B1": float(a.A[0]), "A.B2": float(a.A[1]),
            "A.B3": float(a.A[2]), "D0": ap.D0_g, "D2": ap.D2_g_per_g2, "D3": ap.D3_g_per_g3,
        }
        out.update({(inst, n): float(v) for n, v in vals.items()})
    return out
