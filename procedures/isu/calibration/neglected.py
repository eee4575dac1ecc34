"""The terms the printed gyro closed forms neglect, put back by iteration (issue 19).

Chart II-15's forms (``gyro_equations``) take the nominal G, O, S in the g and g^2 terms
of Chart IV-2. The true axes are off by the misalignments the same day measures (G.B_j,
a few hundred arcsec): at position 9 gyro 1 sees g B_I (G.B2) beside g B_S (S.B2), so B_S
is off by B_I (G.B2), about 1e-3 deg/hr/g, a fixed error its sigma left out (and likewise
B_O, B_I and the compliances). The forms stay the manual's step: the reduced rates of the
static positions 7-15 are corrected by what the full Chart IV-2 model (estimated G, O and S
squared up to it as in ``forward``) adds over the nominal-axis model at the current
estimates, and the printed forms are applied again; two passes leave under 1e-6 deg/hr/g.

No position separates a turn of O and S about G (the simulator's spin-axis rotation): it
only relabels B_O, B_S and the compliances among themselves. Chart II-5 has no row for it,
and the constants are those on the axes the model above uses (``forward.lab_axes``), which
is what a navigation program compensates with; laboratory/isu/truth.py reads the truth on
the same axes.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from procedures.isu.calibration.forward import NOMINAL_AXES, GyroModel
from procedures.isu.calibration.geometry import FIRST_COLUMN
from procedures.isu.calibration.gyro_equations import Value, gyro_estimates
from procedures.isu.calibration.inputs import Constants
from procedures.isu.calibration.reduce import Key

PASSES = 2
STATIC = range(7, 16)


def _dot(a: list[float], b: list[float]) -> float:
    """a . b of 3-vectors, summed left to right as numpy's 3-element dot sums them (no FMA:
    the same bits, without a numpy scalar per product)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _g_args(axes: tuple[list[float], list[float], list[float]], up: list[float],
            g: float) -> tuple[float, ...]:
    """``GyroModel._deg_hr``'s arguments for the g terms with up ``up`` and axes (G, O, S)."""
    a = [g * x for x in up]
    ag, ao, as_ = (_dot(a, x) for x in axes)
    return (ag, ao, as_, 0.0, 0.0, ag * ag, as_ * as_, ag * as_, ao * as_, ag * ao, 0.0, 0.0)


def _axes(m: GyroModel) -> tuple[list[float], list[float], list[float]]:
    return m.G.tolist(), m.O.tolist(), m.S.tolist()


def g_terms(m: GyroModel, u: np.ndarray, g: float) -> float:
    """R and the g, g^2 terms of Chart IV-2 (deg/hr) with up ``u`` (body), no input rate."""
    return m._deg_hr(*_g_args(_axes(m), u.tolist(), g))


_UP = {m: FIRST_COLUMN[m].tolist() for m in STATIC}
# the nominal axes' g terms per (gyro, g): fixed, whatever the coefficients (issue 17)
_NOMINAL_ARGS: dict[tuple[int, float], dict[int, tuple[float, ...]]] = {}


def _nominal_args(k: int, g: float) -> dict[int, tuple[float, ...]]:
    if (k, g) not in _NOMINAL_ARGS:
        if len(_NOMINAL_ARGS) > 64:
            _NOMINAL_ARGS.clear()
        g0, o0, s0 = NOMINAL_AXES[k - 1]
        axes = (g0.tolist(), o0.tolist(), s0.tolist())
        _NOMINAL_ARGS[(k, g)] = {m: _g_args(axes, _UP[m], g) for m in STATIC}
    return _NOMINAL_ARGS[(k, g)]


def neglected(est: Mapping[str, Value], c: Constants, k: int) -> dict[int, float]:
    """Pulses/s the printed forms leave out at each static position, at estimates ``est``."""
    full = GyroModel.from_estimates(k, dict(est))
    nominal = _nominal_args(k, c.g)
    scale = 1.0 / (3600.0 * full.dphi_deg)
    axes = _axes(full)
    return {m: (full._deg_hr(*_g_args(axes, _UP[m], c.g)) - full._deg_hr(*nominal[m]))
            * scale for m in STATIC}


def corrected_gyro_estimates(z: Mapping[Key, float], c: Constants, k: int
                             ) -> dict[str, Value]:
    """Chart II-5 gyro rows of gyro k: the printed forms applied to the rates less the
    neglected terms, iterated (``PASSES``); the printed forms' own when G is undetermined."""
    est = gyro_estimates(z, c, k)
    if any(est.get(f"G.B{j}") is None for j in (1, 2, 3)):
        return est
    for _ in range(PASSES):
        d = neglected(est, c, k)
        zc = dict(z)
        for m, x in d.items():
            if ("G", k, m) in zc:
                zc[("G", k, m)] = z[("G", k, m)] - x
        est = gyro_estimates(zc, c, k)
    return est

