"""Accelerometer calibration equations (report 000, II-4.3), derived from Chart IV-1.

F = f2 - f1 = D1 (u + D0 + D2 u^2 + D3 u^3), u = g A_k.up in g, with a_j = A_k.B_j and
P_j = [D1 (A_k.B_j)]. With B_j up/down (pair m, m+1; m = 7, 9, 11 for j = 1, 2, 3):
  (F_m - F_m+1) / (2g) = P_j + g^2 (D1 D3) a_j^3     (a_j^3 ~ 1 for j = k, ~ 0 otherwise)
  (F_m + F_m+1) / 2    = D1 D0 + g^2 (D1 D2) a_j^2   (a_j^2 ~ 1 for j = k, ~ 0 otherwise)
At the bisector position (13 for accelerometers 1 and 2, 14 for 3), with partner axis p:
  sqrt2 F / g = P_k + P_p + sqrt2 (D1 D0)/g + (g/sqrt2)(D1 D2) + (g^2/2)(D1 D3).
So V = P_k + g^2 X and W = P_k + (g^2/2) X (X = D1 D3), solved together (X = 2(V - W)/g^2,
P_k = 2W - V), or, without the bisector (Chart II-15 step 7), P_k = V - g^2 X_last.
D1 = sqrt(sum_j P_j^2); the P_j of a pair not measured is dropped (second order: a few 1e-8).

Neglected: D2 and D3 times misalignments (below 1e-8 of D1). The printed equations agree with
this derivation; D1 D0 is the mean of whichever horizontal pairs were measured (the print
gives both as equal).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from procedures.isu.calibration.reduce import Key

SQ2 = math.sqrt(2.0)
Value = float | None
ACCEL_PARAMS = ("D1", "A.B1", "A.B2", "A.B3", "D0", "D2", "D3")
BISECTOR = {1: (13, 2), 2: (13, 1), 3: (14, 1)}  # accelerometer -> (position, partner axis)


def pair_position(j: int) -> int:
    """First position of the pair with B_j up then down (7, 9, 11)."""
    return 2 * j + 5


def accel_estimates(z: Mapping[Key, float], g: float, k: int) -> dict[str, Value]:
    """Chart II-5 accelerometer rows: D1 (pulses/s)/g, A.B_j, D0 g, D2 g/g^2, D3 g/g^3."""
    out: dict[str, Value] = {p: None for p in ACCEL_PARAMS}

    def F(m: int) -> Value:
        return z.get(("F", k, m))

    def diff(j: int) -> Value:
        a, b = F(pair_position(j)), F(pair_position(j) + 1)
        return None if a is None or b is None else (a - b) / (2.0 * g)

    def half_sum(j: int) -> Value:
        a, b = F(pair_position(j)), F(pair_position(j) + 1)
        return None if a is None or b is None else 0.5 * (a + b)

    others = [j for j in (1, 2, 3) if j != k]
    P: dict[int, Value] = {j: diff(j) for j in others}
    sums = [s for s in (half_sum(j) for j in others) if s is not None]
    d1d0 = sum(sums) / len(sums) if sums else None
    own = half_sum(k)
    d1d2 = None if own is None or d1d0 is None else (own - d1d0) / g**2
    V = diff(k)
    m45, partner = BISECTOR[k]
    W = None
    f45, p_partner = F(m45), P[partner]
    if f45 is not None and p_partner is not None and d1d0 is not None and d1d2 is not None:
        W = SQ2 * f45 / g - p_partner - SQ2 * d1d0 / g - g / SQ2 * d1d2
    X: Value = None
    if V is not None and W is not None:
        X = 2.0 * (V - W) / g**2
        P[k] = 2.0 * W - V
    elif V is not None and ("X", k, 0) in z:  # Chart II-15 step 7: last (D1 D3) supplied
        P[k] = V - g**2 * z[("X", k, 0)]
    else:
        return out
    d1 = math.sqrt(sum(p * p for p in P.values() if p is not None))
    out["D1"] = d1
    for j in (1, 2, 3):
        pj = P.get(j)
        out[f"A.B{j}"] = None if pj is None else pj / d1
    out["D0"] = None if d1d0 is None else d1d0 / d1
    out["D2"] = None if d1d2 is None else d1d2 / d1
    out["D3"] = None if X is None else X / d1
    return out
