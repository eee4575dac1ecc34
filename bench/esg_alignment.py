"""Mirror and pickoff alignment as adjustments (docs/esg-options.md): a rack misaligned
before step 1 by a shim and a pickoff-1 translation, calibrated with adjust_alignment;
per case the coning measured before and after each adjustment beside the simulator's
truth, and the true readout rms. With ``remount``: pickoff 2 misaligned too, and the run
with remount_alignment (sheet ESG-PA2). With ``pickoff3``: pickoff 3 misaligned as well,
its tilt towards mirror 1 measured and translated out after step 3 (procedures.esg.pickoff3).
With ``pickoff3m2``: pickoff 3 translated along both axes, both its tilts measured and
removed after step 3 (pickoff3_mirror2); START, the index of the first of its cases to run
(default 0), resumes an interrupted series.

    python bench/esg_alignment.py [remount | pickoff3 | pickoff3m2 [START]]
"""

from __future__ import annotations

import json
import tempfile
from collections.abc import Callable
from pathlib import Path

from _args import parser

from laboratory.esg.calibration import run_esg_calibration
from laboratory.esg.truth import (
    true_pickoff1_coning_arcsec,
    true_pickoff3_spindle_tilt_arcsec,
    true_pickoff3_tilts_arcsec,
    true_pickoff_coning_arcsec,
    true_pickoff_mirror_arcsec,
)
from procedures.esg.acquisition import EsgPlan
from sim.units import ARCSEC
from station.racks.esg import EsgRack

# (seed, shim x, shim y, translation a, translation b), arcsec: the table's cases
CASES = ((1, 15.0, -10.0, 40.0, -30.0), (2, 15.0, -10.0, 40.0, -30.0),
         (3, 15.0, -10.0, 40.0, -30.0), (1, -40.0, 25.0, -90.0, 80.0),
         (4, 5.0, 2.0, 60.0, 0.0))
# (seed, pickoff-2 translation a, b), arcsec, with the first case's shim and pickoff 1
REMOUNT_CASES = ((1, 40.0, -30.0), (2, 40.0, -30.0), (3, -70.0, 50.0), (4, 0.0, 90.0),
                 (5, 25.0, 10.0))
# (seed, pickoff-3 translation along c1, c2), arcsec, with the remount cases' first set-up
PICKOFF3_CASES = ((1, 40.0, 0.0), (2, -35.0, 0.0), (3, 60.0, 0.0), (4, -25.0, 0.0),
                  (5, 50.0, 0.0))
# the same seeds with pickoff 3 translated along c2 too, for pickoff3_mirror2
PICKOFF3_M2_CASES = ((1, 40.0, 30.0), (2, -35.0, 20.0), (3, 60.0, -40.0), (4, -25.0, -30.0),
                     (5, 50.0, 35.0))


def calibrated(seed: int, misalign: list[tuple[int, float, float]],
               shim: tuple[float, float], plan: EsgPlan,
               keep: Callable[[str], bool]) -> tuple[EsgRack, dict, dict]:
    """One calibration of a rack shimmed by ``shim`` and with pickoffs translated
    (``misalign``: (pickoff, a, b)) before step 1: (its rack, the run's results, the
    readings of the journal's steps ``keep`` selects)."""
    racks: list[EsgRack] = []

    def hook(rack: EsgRack) -> None:
        racks.append(rack)
        rack.world.shim(*shim)
        for k, a, b in misalign:
            rack.world.translate_pickoff(k, a, b)

    steps = {}
    with tempfile.TemporaryDirectory() as d:
        res = run_esg_calibration(seed, Path(d), rack_hook=hook, with_study=False, plan=plan)
        for line in (Path(d) / "journal.jsonl").read_text().splitlines():
            j = json.loads(line)
            if j.get("kind") == "step" and keep(j["step"]):
                steps[j["step"]] = j["reading"]
    return racks[0], res, steps


def one(seed: int, x: float, y: float, a: float, b: float) -> dict:
    """One adjusted calibration's figures."""
    rack, res, steps = calibrated(
        seed, [(1, a, b)], (x, y), EsgPlan(latitude_deg=0.0, adjust_alignment=True),
        lambda k: k == "1" or k[:2] in ("1.", "PA"))
    w = rack.world
    return {"steps": {k: {f: v.get(f) for f in ("coning_radius_arcsec", "coning_arcsec",
                                                "sigma_arcsec")}
                      for k, v in steps.items() if k != "PA.tilt"},
            "true_mount_after": w.case.coning_rad / ARCSEC,
            "true_pickoff_after": true_pickoff1_coning_arcsec(w),
            "true_readout": [s["true_readout_rms_arcsec"] for s in res["schedules"]]}


def remounted(seed: int, a: float, b: float) -> dict:
    """One calibration with pickoff 2 misaligned by (a, b) and aligned in ESG-PA2."""
    rack, res, steps = calibrated(
        seed, [(1, 40.0, -30.0), (2, a, b)], (15.0, -10.0),
        EsgPlan(latitude_deg=0.0, remount_alignment=True), lambda k: k.startswith("PA2."))
    w = rack.world
    turns = [k for k in steps if k == "PA2.1" or k.startswith("PA2.translate-")]
    return {"p2_off_mirror2_before": true_pickoff_mirror_arcsec(w, 2, 0.0),
            "mirror2": [steps[k]["coning_radius_arcsec"] for k in steps
                        if k == "PA2.mount" or k.startswith("PA2.shim-")],
            "turns": [(steps[k]["coning_arcsec"], steps[k]["sigma_arcsec"],
                       true_pickoff_coning_arcsec(w, 2, steps[k]["t_s"][-1]))
                      for k in turns],
            "p2_off_mirror2_after": true_pickoff_mirror_arcsec(w, 2),
            "true_readout": [s["true_readout_rms_arcsec"] for s in res["schedules"]]}


def pickoff3(seed: int, a: float, b: float) -> dict:
    """One calibration with pickoff 3 translated by (a, b) beforehand: its tilt towards
    mirror 1 measured and removed after step 3."""
    rack, res, steps = calibrated(
        seed, [(1, 40.0, -30.0), (2, 40.0, -30.0), (3, a, b)], (15.0, -10.0),
        EsgPlan(latitude_deg=0.0, remount_alignment=True), lambda k: k.startswith("3.p3"))
    w = rack.world
    turns = list(steps)
    return {"before": true_pickoff3_tilts_arcsec(w, 0.0),
            "turns": [(steps[k]["tilt_arcsec"], steps[k]["sigma_arcsec"],
                       true_pickoff3_spindle_tilt_arcsec(w, steps[k]["along"]["t_s"][-1]),
                       steps[k]["reversed"]["t_s"][-1] - steps[k]["along"]["t_s"][0])
                      for k in turns],
            "after": true_pickoff3_tilts_arcsec(w),
            "true_readout": [s["true_readout_rms_arcsec"] for s in res["schedules"]]}


def pickoff3_m2(seed: int, a: float, b: float) -> dict:
    """One calibration with pickoff 3 translated by (a, b) beforehand: both its tilts
    measured and removed after step 3 (pickoff3_mirror2); the lab time of the run."""
    rack, res, steps = calibrated(
        seed, [(1, 40.0, -30.0), (2, 40.0, -30.0), (3, a, b)], (15.0, -10.0),
        EsgPlan(latitude_deg=0.0, remount_alignment=True, pickoff3_mirror2=True),
        lambda k: k.startswith("3.p3") or k in ("13",))
    w = rack.world
    turns = [k for k in steps if "tilt_arcsec" in steps[k]]
    return {"before": true_pickoff3_tilts_arcsec(w, 0.0),
            "turns": [(k, steps[k].get("translation_arcsec"), steps[k]["tilt_arcsec"],
                       steps[k]["sigma_arcsec"],
                       true_pickoff3_spindle_tilt_arcsec(w, steps[k]["along"]["t_s"][-1]),
                       true_pickoff3_tilts_arcsec(w, steps[k]["along"]["t_s"][-1])[:2])
                      for k in turns],
            "p3_span_h": (steps[turns[-1]]["reversed"]["t_s"][-1]
                          - steps[turns[0]]["along"]["t_s"][0]) / 3600.0,
            "lab_h": w.now / 3600.0,
            "after": true_pickoff3_tilts_arcsec(w),
            "true_readout": [s["true_readout_rms_arcsec"] for s in res["schedules"]]}


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__)
    ap.add_argument("mode", nargs="?", choices=("remount", "pickoff3", "pickoff3m2"),
                    help="the cases to run (default: mirror and pickoff-1 alignment)")
    ap.add_argument("start", metavar="START", nargs="?", type=int, default=None,
                    help=f"pickoff3m2 only: the first of its {len(PICKOFF3_M2_CASES)} cases "
                    "to run (default 0)")
    a = ap.parse_args(argv)
    if a.start is not None and a.mode != "pickoff3m2":
        ap.error("START goes with pickoff3m2 only")
    if a.mode == "pickoff3m2":
        for pcase in PICKOFF3_M2_CASES[a.start or 0:]:
            print(pcase, json.dumps(pickoff3_m2(*pcase), indent=None), flush=True)
        return
    if a.mode == "pickoff3":
        for pcase in PICKOFF3_CASES:
            print(pcase, json.dumps(pickoff3(*pcase), indent=None), flush=True)
        return
    if a.mode == "remount":
        for rcase in REMOUNT_CASES:
            print(rcase, json.dumps(remounted(*rcase), indent=None))
        return
    for case in CASES:
        print(case, json.dumps(one(*case), indent=None))


if __name__ == "__main__":
    main()
