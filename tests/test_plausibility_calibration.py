"""The calibration's own checks (procedures/isu/calibration/checks.py) on synthetic days
(tests/test_calibration_math.make_data: the instrument models with the lab's noise):
nothing judged off on a normal day, and one garbled count found and named, whether it sits
in a redundant datum (a turning position's gyro count) or in a vertical accelerometer
position whose difference f2 - f1 nothing repeats (the string sums catch it)."""

from __future__ import annotations

import numpy as np
import pytest
from test_calibration_math import TRUTH, make_data

from procedures.isu.calibration import NoiseSpec, calibrate
from procedures.isu.calibration.checks import K_RESULT, check_residuals, check_string_sums
from procedures.isu.calibration.inputs import AccelPosition, GyroPosition
from procedures.isu.plausibility import Implausible

SPEC = NoiseSpec()


def rows_of(data):
    """The Calibration Results rows, with Q_II and Q_IS as the special experiments would
    give them (here: the truth, to a negligible sigma)."""
    out = []
    for r in calibrate(data, SPEC):
        if r.parameter in ("Q_II", "Q_IS"):
            q = TRUTH.gyros[int(r.instrument[-1]) - 1]["coef"][r.parameter]
            r = r.model_copy(update={"estimate": q, "sigma": abs(q) * 1e-6})
        out.append(r)
    return out


@pytest.fixture(scope="module")
def days():
    rng = np.random.default_rng(7)
    return [make_data(rng, SPEC) for _ in range(4)]


def test_normal_days_are_not_judged_off(days):
    for data in days:
        rows = rows_of(data)
        res = check_residuals(data, rows, SPEC)
        sums = check_string_sums(data, rows, SPEC)
        judged = res["residuals"]
        assert sum(k.startswith("gyro") for k in judged) >= 9  # the turning pair sums
        assert sum(k.startswith("accel") for k in judged) >= 3 and len(sums) >= 15
        worst = max([abs(v["z"]) for v in res["residuals"].values()]
                    + [abs(z) for z in sums.values()])
        assert worst < K_RESULT - 1.0


def test_a_garbled_turning_count_is_found(days):
    data = days[0]
    p = data.gyro[3]
    delta = list(p.delta)
    delta[1] += 40  # counter 3 (gyro 2): a digit changed, 40 pulses
    bad = data.model_copy(update={"gyro": {**data.gyro, 3: GyroPosition(
        n1=p.n1, delta=tuple(delta), t0=p.t0, t1=p.t1, n_phi=p.n_phi)}})
    with pytest.raises(Implausible) as e:
        check_residuals(bad, rows_of(bad), SPEC)
    assert str(e.value).startswith("counter3 (gyro 2)")
    assert "Chart II-6 position " in str(e.value)


def test_a_garbled_vertical_string_count_is_found(days):
    """Accelerometer 1 up (position 7): its f2 - f1 fixes D1, D2 and D3 with nothing to
    repeat it; one digit of string 2's clock count changed (1000 ticks) still shows in f1 + f2."""
    data = days[1]
    p = data.accel[7]
    n1 = dict(p.n1)
    n1[(1, 2)] += 1000
    bad = data.model_copy(update={"accel": {**data.accel, 7: AccelPosition(
        gamma=p.gamma, n1=n1, t0=p.t0, t1=p.t1, t_level=p.t_level)}})
    rows = rows_of(bad)
    check_residuals(bad, rows, SPEC)  # the difference alone has no redundancy here
    with pytest.raises(Implausible) as e:
        check_string_sums(bad, rows, SPEC)
    assert str(e.value).startswith("counter1 and counter2 (accelerometer 1's strings)")
    assert "position 7" in str(e.value)
