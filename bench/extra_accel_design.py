"""Which extra accelerometer positions (issue 19, beyond the manual) bring the all-positions
D1 sigma 1.5x below the closed forms', from the covariance model alone: per lab (the
default and random labs of tests/random_labs.py, charts II-13 and II-14 measured), extra
positions are added with noise-free readings at the simulator's truth and the plan's gates,
and the Cramer-Rao bound of the extended design (which the fit reaches within 1.04x) is
compared with the closed forms' sigma.

    PYTHONPATH=.:tests nice -n 10 python bench/extra_accel_design.py [N_LABS]
"""

from __future__ import annotations

import math

import numpy as np
from _args import count, parser
from random_labs import calibration_day, random_lab

from procedures.isu.calibration import CalibrationData, NoiseSpec
from procedures.isu.calibration.all_positions import cramer_rao
from procedures.isu.calibration.compute import constants_covariance
from procedures.isu.calibration.forward import AccelModel
from procedures.isu.calibration.geometry import frame_at, setting_for
from procedures.isu.calibration.inputs import EXTRA_FIRST, ExtraAccelPosition
from procedures.isu.extra_positions import SET_S, tilted_ups
from station.config.isu import load_config

VERTICAL_S, HORIZONTAL_S, F0 = 600.0, 1800.0, 20000.0
# the plan's gates per accelerometer (vertical within 45 deg), and the vertical gate for all
GATES = ((VERTICAL_S, HORIZONTAL_S), (VERTICAL_S, VERTICAL_S))


def gate_of(a_up: float, vertical_s: float, horizontal_s: float) -> float:
    """The vertical gate for an accelerometer nearer vertical than horizontal, else the
    horizontal one (the manual counts the bisector positions with the horizontal gate)."""
    return vertical_s if abs(a_up) > math.sqrt(0.5) + 1e-9 else horizontal_s


def cone_ups(tilts: list[float]) -> list[np.ndarray]:
    """Alternative: accelerometer k tilted by theta toward the bisector of the other two."""
    out = []
    for th in tilts:
        c, s = math.cos(math.radians(th)), math.sin(math.radians(th)) / math.sqrt(2.0)
        for k in range(3):
            u = np.full(3, s)
            u[k] = c
            out += [u, -u]
    return out


def extend(doc: dict, truth: dict, ups: list[np.ndarray], vertical_s: float,
           horizontal_s: float) -> CalibrationData:
    data = CalibrationData.model_validate(doc)
    s1 = data.constants.s1_t
    t_bi = np.asarray(data.geometry.t_bi)
    t = max(p.t1 for p in data.accel.values()) + SET_S
    extra = {}
    for i, u in enumerate(ups):
        if i % 2 == 0:  # the second of each pair: phi3 + 180 deg (as the procedure)
            p3, p4 = setting_for(u, t_bi)
        else:
            p3 += math.pi
        fr = frame_at(t_bi, p3, p4)
        gamma, n1 = {}, {}
        gate = 0.0
        for k in (1, 2, 3):
            a = truth[f"accel{k}|A.B1"], truth[f"accel{k}|A.B2"], truth[f"accel{k}|A.B3"]
            am = AccelModel(truth[f"accel{k}|D1"], np.array(a), truth[f"accel{k}|D0"],
                            truth[f"accel{k}|D2"], truth[f"accel{k}|D3"])
            f = am.difference(fr[:, 0], data.constants)
            gk = gate_of(float(fr[:, 0][k - 1]), vertical_s, horizontal_s)
            gate = max(gate, gk)
            for ell, fl in ((1, 20000.0 - f / 2), (2, 20000.0 + f / 2)):
                gamma[(k, ell)] = float(math.ceil(gk * F0))
                n1[(k, ell)] = gamma[(k, ell)] / (fl * s1)
        extra[EXTRA_FIRST + i] = ExtraAccelPosition(
            gamma=gamma, n1=n1, t0=t, t1=t + gate, t_level=t - 2.5, up=tuple(fr[:, 0]),
            north=tuple(fr[:, 1]), setting_deg=(math.degrees(p3), math.degrees(p4)))
        t += gate + SET_S
    return data.model_copy(update={"extra_accel": extra})


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__)
    ap.add_argument("n", metavar="N_LABS", nargs="?", type=count, default=4,
                    help="labs: the default and random labs 1..N_LABS-1 (default 4)")
    a = ap.parse_args(argv)
    n = a.n
    s2 = 1.0 / math.sqrt(2.0)
    diag = [np.ones(3) / math.sqrt(3.0), -np.ones(3) / math.sqrt(3.0)]
    designs = {"plane 30": tilted_ups([30.0]), "plane 45": tilted_ups([45.0]),
               "plane 60": tilted_ups([60.0]),
               "plane 45 3pr": [*tilted_ups([45.0]), np.array([s2, 0, s2]), -np.array([s2, 0, s2])],
               "plane 30 2pr": tilted_ups([30.0])[:4],
               "diag 1pr": diag, "cone 35": cone_ups([35.0]),
               "plane 30,60": tilted_ups([30.0, 60.0]),
               "bisect+-": [np.array([s2, s2, 0]), -np.array([s2, s2, 0]),
                            np.array([s2, 0, s2]), -np.array([s2, 0, s2])]}
    labs = [("default", load_config(seed=1))] + [(f"lab{s}", random_lab(s)) for s in range(1, n)]
    for name, cfg in labs:
        doc, ndoc, truth, _ = calibration_day(cfg, ("II-13", "II-14"))
        noise = NoiseSpec.model_validate(ndoc)
        data = CalibrationData.model_validate(doc)
        est, rows, cov = constants_covariance(data, noise)
        tr = {tuple(k.split("|")): v for k, v in truth.items()}
        cf = {r: math.sqrt(cov[i, i]) for i, r in enumerate(rows)}
        base_rows, base = cramer_rao(data, tr, noise, closed=est)
        b0 = {r: math.sqrt(base[i, i]) for i, r in enumerate(base_rows)}
        line = [f"{name:8s} manual " + " ".join(
            f"{cf[(f'accel{k}', 'D1')] / b0[(f'accel{k}', 'D1')]:.2f}" for k in (1, 2, 3))]
        for dname, ups in designs.items():
            for vs, hs in GATES:
                ext = extend(doc, truth, ups, vs, hs)
                crows, crb = cramer_rao(ext, tr, noise, closed=est)
                s = {r: math.sqrt(crb[i, i]) for i, r in enumerate(crows)}
                hours = sum(p.t1 - p.t0 + SET_S for p in ext.extra_accel.values()) / 3600
                ratios = [cf[(f"accel{k}", "D1")] / s[(f"accel{k}", "D1")] for k in (1, 2, 3)]
                d3 = [cf[(f"accel{k}", "D3")] / s[(f"accel{k}", "D3")] for k in (1, 2, 3)]
                line.append(f"  {dname:12s} n={len(ups):2d} {hours:4.1f} h  D1 "
                            + " ".join(f"{r:.2f}" for r in ratios) + "  D3 "
                            + " ".join(f"{r:.2f}" for r in d3))
        print("\n".join(line), flush=True)


if __name__ == "__main__":
    main()
