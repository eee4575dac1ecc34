"""The terms the printed gyro closed forms neglect (procedures.isu.calibration.neglected).

On noise-free data from an independent implementation of Charts IV-2 and I-4
(tests/test_calibration_math.py): the printed forms miss B and C by unbalance times
misalignment (up to 1.1e-3 deg/hr/g at the default); with the misalignment put back, what is
left of B_O and B_S is exactly the turn of O, S about G that no position measures
(-e B_S and +e B_O), and the rest is below 5e-5 deg/hr(/g, /g^2). The truth a day's record
compares with (laboratory.isu.truth) is read on the calibration's axes, so it holds that turn.
"""

from __future__ import annotations

from test_calibration_math import AS, CFG, NOISE_FREE, TRUTH

from laboratory.isu.truth import on_lab_axes
from procedures.isu.calibration import gyro_equations as ge
from procedures.isu.calibration.compute import estimate
from procedures.isu.calibration.reduce import reduce
from sim.isu.unit import Gyro
from station.config.isu import load_config

TERMS = ("R", "B_I", "B_O", "B_S", "C_II", "C_SS", "C_IS", "C_OS", "C_IO")


def test_misalignment_put_back_leaves_only_the_spin_axis_turn():
    z = reduce(NOISE_FREE).values
    est = estimate(z, NOISE_FREE.constants)
    truth = TRUTH.expected()
    worst_printed = 0.0
    for k in (1, 2, 3):
        printed = ge.gyro_estimates(z, NOISE_FREE.constants, k)
        coef = TRUTH.gyros[k - 1]["coef"]
        e = CFG["isu"]["gyros"][k - 1]["spin_axis_rotation_arcsec"] * AS
        spin = {"B_O": -e * coef["B_S"], "B_S": e * coef["B_O"]}
        for p in TERMS:
            row = (f"gyro{k}", p)
            worst_printed = max(worst_printed, abs(printed[p] - truth[row]))
            left = est[row] - truth[row] - spin.get(p, 0.0)
            assert abs(left) < 5e-5, (row, est[row] - truth[row], spin.get(p))
    assert worst_printed > 1e-3  # the defect the correction removes


def test_the_records_truth_is_on_the_calibrations_axes():
    """laboratory.isu.truth's gyro terms equal the estimates of noise-free data (the
    generator's own truth, gyro axes, misses B_O or B_S by the turn: more than 5e-5)."""
    est = estimate(reduce(NOISE_FREE).values, NOISE_FREE.constants)
    truth, cfg = TRUTH.expected(), load_config()
    turned = 0.0
    for k in (1, 2, 3):
        lab = on_lab_axes(k, Gyro(k - 1, cfg.isu.gyros[k - 1], cfg.seed))
        for p in TERMS[1:]:
            row = (f"gyro{k}", p)
            assert abs(est[row] - lab[p]) < 5e-5, (row, est[row], lab[p])
            turned = max(turned, abs(lab[p] - truth[row]))
    assert turned > 5e-5
