"""Ground truth of the simulated ISU in the units of the Calibration Results Sheet.

Only the station layer may look at the simulator: procedures estimate, this module says
what the right answers were, so results can show estimate, truth and error side by side.
"""

from __future__ import annotations

from procedures.isu.sheets import ARCSEC_PER_DEG
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


def calibration_truth(world: World) -> dict[tuple[str, str], float]:
    out: dict[tuple[str, str], float] = {}
    for k, g in enumerate(world.isu.gyros, start=1):
        p = g.p
        inst = f"gyro{k}"
        vals = {
            "DeltaPhi": p.scale_factor_arcsec_per_pulse / ARCSEC_PER_DEG,  # Chart II-5
            "G.B1": float(g.G[0]), "G.B2": float(g.G[1]), "G.B3": float(g.G[2]),
            "R": p.R_deg_hr, "B_I": p.B_I_deg_hr_g, "B_O": p.B_O_deg_hr_g,
            "B_S": p.B_S_deg_hr_g, "C_II": p.C_II_deg_hr_g2, "C_SS": p.C_SS_deg_hr_g2,
            "C_IS": p.C_IS_deg_hr_g2, "C_OS": p.C_OS_deg_hr_g2, "C_IO": p.C_IO_deg_hr_g2,
            "Q_II": p.Q_II_hr_deg, "Q_IS": p.Q_IS_hr_deg, "J": p.J_hr,
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
