"""Gyro calibration equations (report 000, II-4.2), derived from Chart IV-2 and the positions.

Rates are pulses/s (``reduce``); Earth rate enters in deg/s; [x/DeltaPhi] in pulses/s per
unit of x's input; [(G_k.B_j)/DeltaPhi] in pulses/deg. With a = g u and
w = W cos(lambda) u + W sin(lambda) n (u, n: body components of up and north, n from the
survey's second column of T^BRm), the rate of gyro k at a static position is
  rho = sum_j [(G_k.B_j)/DeltaPhi] w_j + [R] + g([B_I] u.G + [B_O] u.O + [B_S] u.S)
        + g^2([C_II](u.G)^2 + [C_SS](u.S)^2 + [C_IS](u.G)(u.S) + [C_OS](u.O)(u.S)
              + [C_IO](u.G)(u.O)),
[x] = x/DeltaPhi, with G, O, S the nominal axes in the g-dependent terms. Pair differences
(up/down about north) keep the odd terms and the vertical Earth rate; pair sums keep the
even terms and the north Earth rate.

Neglected by these closed forms (as by the print): the misalignment of G, O, S in the g
terms (unbalance times a few hundred arcsec, about 1e-3 deg/hr; compliance times the same),
Q_II and Q_IS at Earth rate (below 1e-6 deg/hr), J (zero at rest). Kept where the print
drops them: every element of the survey column in the north Earth-rate terms; the one along
the position's up axis (nominally zero, e.g. T12^BR1) is used whenever its [G.B] is known,
so it never adds a prerequisite to Chart II-16.

Where the print disagrees with the derivation the derived form is used (comments cite the
chart); all other lines agree with the print.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

from procedures.isu.calibration.geometry import FIRST_COLUMN, SURVEY_SOURCE, UP_AXIS
from procedures.isu.calibration.inputs import Constants
from procedures.isu.calibration.reduce import Key

SQ2 = math.sqrt(2.0)
Value = float | None


def _f(fn: Callable[..., float], *args: Value) -> Value:
    """fn(*args), or None when any input is not determined (partial calibration)."""
    return None if any(a is None for a in args) else fn(*args)


def misalignment_over_scale(z: Mapping[Key, float], c: Constants, k: int, j: int) -> Value:
    """[(G_k.B_j)/DeltaPhi]_k, pulses/deg, from positions 2j-1 and 2j (Chart II-15, II-4.2).

    Over whole turns the pair differs only in the sign of the rate along B_j; the inertial
    rate along +R1 (south) is w_T - W sin(lambda), hence the 2 W sin(lambda) of the print,
    with R1 level; ``Constants.w_along_r1`` takes R1's tilt from the survey's phi1 too.
    Without the pair, a supplied ("P", k, j) from an earlier sheet stands in (else None).
    """
    m = 2 * j - 1
    keys = (("G", k, m), ("G", k, m + 1), ("w", 0, m), ("w", 0, m + 1))
    if any(key not in z for key in keys):
        return z.get(("P", k, j))  # an earlier sheet's, when supplied (partial calibration)
    r1, r2, w1, w2 = (z[key] for key in keys)
    return (r1 - r2) / (w1 + w2 + 2.0 * c.w_along_r1 / 3600.0)


class _Terms:
    """The building blocks of the closed forms for one gyro."""

    def __init__(self, z: Mapping[Key, float], c: Constants, k: int) -> None:
        self.z, self.c, self.k = z, c, k
        self.gk = [misalignment_over_scale(z, c, k, j) for j in (1, 2, 3)]
        self.g = c.g
        self.wc = c.w_cos_lambda / 3600.0  # deg/s
        self.ws = c.w_sin_lambda / 3600.0

    def rho(self, m: int) -> Value:
        return self.z.get(("G", self.k, m))

    def gj(self, j: int) -> Value:
        return self.gk[j - 1]

    def half_sum(self, m: int) -> Value:
        return _f(lambda a, b: 0.5 * (a + b), self.rho(m), self.rho(m + 1))

    def half_diff(self, m: int) -> Value:
        return _f(lambda a, b: 0.5 * (a - b), self.rho(m), self.rho(m + 1))

    def north(self, m: int) -> Value:
        """W sin(lambda) sum_j [(G.B_j)/DeltaPhi] T_j2^BR (pair m, m+1 share the column)."""
        col = self.c.t_br_column2.get(SURVEY_SOURCE[m])
        if col is None:
            return None
        s = 0.0
        for j in range(3):
            gj = self.gk[j]
            if gj is None:
                if j == UP_AXIS[m]:  # nominally zero element: dropped, as in the print
                    continue
                return None
            s += gj * col[j]
        return self.ws * s

    def earth(self, m: int) -> Value:
        """Earth-rate term at a bisector position 13, 14 or 15 (all elements needed)."""
        col = self.c.t_br_column2.get(m)
        if col is None or None in self.gk:
            return None
        u = FIRST_COLUMN[m]
        return sum(g * (self.wc * u[j] + self.ws * col[j]) for j, g in enumerate(self.gk))


def _gyro1(t: _Terms) -> dict[str, Value]:
    """Gyro 1: G = B1, O = B3, S = -B2."""
    g, wc = t.g, t.wc
    R = _f(lambda h, n: h - n, t.half_sum(11), t.north(11))
    B_I = _f(lambda d, x: (d - wc * x) / g, t.half_diff(7), t.gj(1))
    B_O = _f(lambda d, x: (d - wc * x) / g, t.half_diff(11), t.gj(3))
    # Chart II-15 (II-4.2) prints -(w cos/g)[G1.B2/DPhi] here: with S = -B2 the sign is +.
    B_S = _f(lambda d, x: (-d + wc * x) / g, t.half_diff(9), t.gj(2))
    C_II = _f(lambda h, r, n: (h - r - n) / g**2, t.half_sum(7), R, t.north(7))
    C_SS = _f(lambda h, r, n: (h - r - n) / g**2, t.half_sum(9), R, t.north(9))
    # Chart II-15 prints the Earth-rate term of C_IS with -2w/g^2: it enters like R, with +.
    C_IS = _f(
        lambda e, r, s, bi, bs, ci, cs: 2 * (e + r - s) / g**2 + SQ2 * (bi - bs) / g + ci + cs,
        t.earth(13),
        R,
        t.rho(13),
        B_I,
        B_S,
        C_II,
        C_SS,
    )
    C_IO = _f(
        lambda e, r, s, bi, bo, ci: 2 * (s - e - r) / g**2 - SQ2 * (bi + bo) / g - ci,
        t.earth(14),
        R,
        t.rho(14),
        B_I,
        B_O,
        C_II,
    )
    C_OS = _f(
        lambda e, r, s, bo, bs, cs: 2 * (e + r - s) / g**2 + SQ2 * (bo - bs) / g + cs,
        t.earth(15),
        R,
        t.rho(15),
        B_O,
        B_S,
        C_SS,
    )
    return {
        "R": R,
        "B_I": B_I,
        "B_O": B_O,
        "B_S": B_S,
        "C_II": C_II,
        "C_SS": C_SS,
        "C_IS": C_IS,
        "C_OS": C_OS,
        "C_IO": C_IO,
    }


def _gyro2(t: _Terms) -> dict[str, Value]:
    """Gyro 2: G = B2, O = B1, S = -B3."""
    g, wc = t.g, t.wc
    R = _f(lambda h, n: h - n, t.half_sum(7), t.north(7))
    B_O = _f(lambda d, x: (d - wc * x) / g, t.half_diff(7), t.gj(1))
    B_I = _f(lambda d, x: (d - wc * x) / g, t.half_diff(9), t.gj(2))
    # Chart II-15 (II-4.2) prints -(w cos/g)[G2.B3/DPhi] here: with S = -B3 the sign is +.
    B_S = _f(lambda d, x: (-d + wc * x) / g, t.half_diff(11), t.gj(3))
    C_II = _f(lambda h, r, n: (h - r - n) / g**2, t.half_sum(9), R, t.north(9))
    C_SS = _f(lambda h, r, n: (h - r - n) / g**2, t.half_sum(11), R, t.north(11))
    C_IO = _f(
        lambda e, r, s, bi, bo, ci: 2 * (s - e - r) / g**2 - SQ2 * (bi + bo) / g - ci,
        t.earth(13),
        R,
        t.rho(13),
        B_I,
        B_O,
        C_II,
    )
    C_OS = _f(
        lambda e, r, s, bo, bs, cs: 2 * (e + r - s) / g**2 + SQ2 * (bo - bs) / g + cs,
        t.earth(14),
        R,
        t.rho(14),
        B_O,
        B_S,
        C_SS,
    )
    C_IS = _f(
        lambda e, r, s, bi, bs, ci, cs: 2 * (e + r - s) / g**2 + SQ2 * (bi - bs) / g + ci + cs,
        t.earth(15),
        R,
        t.rho(15),
        B_I,
        B_S,
        C_II,
        C_SS,
    )
    return {
        "R": R,
        "B_I": B_I,
        "B_O": B_O,
        "B_S": B_S,
        "C_II": C_II,
        "C_SS": C_SS,
        "C_IS": C_IS,
        "C_OS": C_OS,
        "C_IO": C_IO,
    }


def _gyro3(t: _Terms) -> dict[str, Value]:
    """Gyro 3: G = B3, O = B1, S = +B2."""
    g, wc = t.g, t.wc
    R = _f(lambda h, n: h - n, t.half_sum(7), t.north(7))
    B_O = _f(lambda d, x: (d - wc * x) / g, t.half_diff(7), t.gj(1))
    B_S = _f(lambda d, x: (d - wc * x) / g, t.half_diff(9), t.gj(2))
    # Chart II-15 labels this line [B_I/DPhi]_1 (copy slip): it is gyro 3's B_I.
    B_I = _f(lambda d, x: (d - wc * x) / g, t.half_diff(11), t.gj(3))
    C_SS = _f(lambda h, r, n: (h - r - n) / g**2, t.half_sum(9), R, t.north(9))
    C_II = _f(lambda h, r, n: (h - r - n) / g**2, t.half_sum(11), R, t.north(11))
    C_OS = _f(
        lambda e, r, s, bo, bs, cs: 2 * (s - e - r) / g**2 - SQ2 * (bo + bs) / g - cs,
        t.earth(13),
        R,
        t.rho(13),
        B_O,
        B_S,
        C_SS,
    )
    C_IO = _f(
        lambda e, r, s, bi, bo, ci: 2 * (s - e - r) / g**2 - SQ2 * (bi + bo) / g - ci,
        t.earth(14),
        R,
        t.rho(14),
        B_I,
        B_O,
        C_II,
    )
    C_IS = _f(
        lambda e, r, s, bi, bs, ci, cs: 2 * (s - e - r) / g**2 - SQ2 * (bi + bs) / g - ci - cs,
        t.earth(15),
        R,
        t.rho(15),
        B_I,
        B_S,
        C_II,
        C_SS,
    )
    return {
        "R": R,
        "B_I": B_I,
        "B_O": B_O,
        "B_S": B_S,
        "C_II": C_II,
        "C_SS": C_SS,
        "C_IS": C_IS,
        "C_OS": C_OS,
        "C_IO": C_IO,
    }


_FORMS = {1: _gyro1, 2: _gyro2, 3: _gyro3}
GYRO_PARAMS = (
    "DeltaPhi",
    "G.B1",
    "G.B2",
    "G.B3",
    "R",
    "B_I",
    "B_O",
    "B_S",
    "C_II",
    "C_SS",
    "C_IS",
    "C_OS",
    "C_IO",
    "Q_II",
    "Q_IS",
    "J",
)


def gyro_estimates(z: Mapping[Key, float], c: Constants, k: int) -> dict[str, Value]:
    """Chart II-5 gyro rows in lab units: DeltaPhi deg/pulse, G.B_j, R deg/hr, B deg/hr/g,
    C deg/hr/g^2. Q_II, Q_IS, J come from separate experiments: None here."""
    t = _Terms(z, c, k)
    out: dict[str, Value] = {p: None for p in GYRO_PARAMS}
    gk = [x for x in t.gk if x is not None]
    if len(gk) < 3:
        return out  # every constant needs the scale factor (Chart II-16 note)
    dphi = 1.0 / math.sqrt(sum(x * x for x in gk))  # deg/pulse
    out["DeltaPhi"] = dphi  # deg/pulse, as Chart II-5 prints it
    for j in (1, 2, 3):
        out[f"G.B{j}"] = gk[j - 1] * dphi
    for name, v in _FORMS[k](t).items():
        out[name] = None if v is None else v * dphi * 3600.0  # pulses/s -> deg/hr
    return out
