"""Chart II-16: the positions each calibration constant needs, prerequisites in parentheses.

The chart's note applies to every row: "the scale factor (DeltaPhi or D1) is also required
for each other term", i.e. positions 1 to 6 for every gyro constant and D1's positions for
every accelerometer constant. Chart II-15 step 7 adds one alternative: with a last (D1 D3)
supplied, D1 (and with it the other accelerometer constants, not D3) needs only the
accelerometer's own vertical pair instead of the bisector and its prerequisites.
"""

from __future__ import annotations

import re

SPECIAL = "special experiments"

GYRO: dict[str, tuple[str, str, str]] = {
    "DeltaPhi": ("1 to 6", "1 to 6", "1 to 6"),
    "G.B1": ("1, 2", "1, 2", "1, 2"),
    "G.B2": ("3, 4", "3, 4", "3, 4"),
    "G.B3": ("5, 6", "5, 6", "5, 6"),
    "R": ("11, 12 (1 to 4)", "7, 8 (3 to 6)", "7, 8 (3 to 6)"),
    "B_I": ("7, 8 (1, 2)", "9, 10 (3, 4)", "11, 12 (5, 6)"),
    "B_O": ("11, 12 (5, 6)", "7, 8 (1, 2)", "7, 8 (1, 2)"),
    "B_S": ("9, 10 (3, 4)", "11, 12 (5, 6)", "9, 10 (3, 4)"),
    "C_II": ("7, 8 (1 to 6, 11, 12)", "9, 10 (1 to 8)", "11, 12 (1 to 8)"),
    "C_SS": ("9, 10 (1 to 6, 11, 12)", "11, 12 (1 to 8)", "9, 10 (1 to 8)"),
    "C_IS": ("13 (1 to 12)", "15 (1 to 12)", "15 (1 to 12)"),
    "C_OS": ("15 (1 to 6, 9 to 12)", "14 (1 to 8, 11, 12)", "13 (1 to 10)"),
    "C_IO": ("14 (1 to 8, 11, 12)", "13 (1 to 10)", "14 (1 to 8, 11, 12)"),
    "Q_II": (SPECIAL,) * 3,
    "Q_IS": (SPECIAL,) * 3,
    "J": (SPECIAL,) * 3,
}

ACCEL: dict[str, tuple[str, str, str]] = {
    "D1": ("7, 8, 13 (9, 10, D0)", "9, 10, 13 (7, 8, D0)", "11, 12, 14 (7, 8, D0)"),
    "A.B1": ("7, 8", "7, 8", "7, 8"),
    "A.B2": ("9, 10", "9, 10", "9, 10"),
    "A.B3": ("11, 12", "11, 12", "11, 12"),
    "D0": ("9, 10 or 11, 12", "7, 8 or 11, 12", "7, 8 or 9, 10"),
    "D2": ("7, 8 (D0)", "9, 10 (D0)", "11, 12 (D0)"),
    "D3": ("same as D1", "same as D1", "same as D1"),
}

GYRO_UNITS = {
    "DeltaPhi": "deg/pulse",  # Chart II-5's unit (the count-noise figures use arcsec)
    "G.B1": "-",
    "G.B2": "-",
    "G.B3": "-",
    "R": "deg/hr",
    "B_I": "deg/hr/g",
    "B_O": "deg/hr/g",
    "B_S": "deg/hr/g",
    "C_II": "deg/hr/g^2",
    "C_SS": "deg/hr/g^2",
    "C_IS": "deg/hr/g^2",
    "C_OS": "deg/hr/g^2",
    "C_IO": "deg/hr/g^2",
    "Q_II": "hr/deg",
    "Q_IS": "hr/deg",
    "J": "hr",
}
ACCEL_UNITS = {
    "D1": "(pulses/s)/g",
    "A.B1": "-",
    "A.B2": "-",
    "A.B3": "-",
    "D0": "g",
    "D2": "g/g^2",
    "D3": "g/g^3",
}

Alternatives = list[frozenset[int]]


def parse(text: str, refs: dict[str, Alternatives] | None = None) -> Alternatives:
    """Alternative position sets of a chart entry ("7, 8 (1 to 6, 11, 12)", "a or b", "D0")."""
    refs = refs or {}
    out: Alternatives = []
    for alt in text.split(" or "):
        base: set[int] = set()
        subs: Alternatives = [frozenset()]
        for tok in (t.strip() for t in re.split(r"[,()]", alt)):
            if not tok:
                continue
            if tok in refs:
                subs = [s | r for s in subs for r in refs[tok]]
            elif " to " in tok:
                a, b = (int(x) for x in tok.split(" to "))
                base |= set(range(a, b + 1))
            else:
                base.add(int(tok))
        out += [frozenset(base) | s for s in subs]
    return out


def _and(x: Alternatives, y: Alternatives) -> Alternatives:
    return [a | b for a in x for b in y]


def gyro_requirement(param: str, k: int) -> Alternatives | None:
    """Position sets (any one suffices) that determine gyro k's constant; None if special."""
    text = GYRO[param][k - 1]
    if text == SPECIAL:
        return None
    alts = parse(text)
    return alts if param == "DeltaPhi" else _and(alts, parse(GYRO["DeltaPhi"][k - 1]))


def accel_requirement(param: str, k: int, last_d1d3: bool = False) -> Alternatives:
    """Position sets that determine accelerometer k's constant (step 7 if ``last_d1d3``)."""
    d0 = parse(ACCEL["D0"][k - 1])
    d1 = parse(ACCEL["D1"][k - 1], {"D0": d0})
    if param == "D3":
        return d1
    if last_d1d3:
        own = 2 * k + 5
        d1 = d1 + [frozenset({own, own + 1})]
    if param == "D1":
        return d1
    return _and(parse(ACCEL[param][k - 1], {"D0": d0}), d1)


def satisfied(alts: Alternatives, positions: set[int] | frozenset[int]) -> bool:
    return any(a <= positions for a in alts)
