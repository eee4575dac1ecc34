"""Carry-forward (Chart II-15 steps 3 and 7, Chart II-16): a partial calibration takes what it
does not measure from an earlier Calibration Results Sheet (Chart II-5).

The earlier sheet supplies (a) the prerequisites in Chart II-16's parentheses, entered as data
with their sigmas so the new constants carry their uncertainty: [(G_k.B_j)/DeltaPhi] for the
turning pairs not measured, and the last (D1 D3) of each accelerometer without its bisector
position (step 7); and (b) every constant the run's positions do not determine, copied with
its sigma. Each such row names its source in its note.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from procedures.isu.sheets import CalibrationResults, ResultRow
from station.errors import CheckFailed

BISECTOR = {1: 13, 2: 13, 3: 14}  # accelerometer k -> its bisector position (Chart II-16)


@dataclass(frozen=True)
class PriorSheet:
    """An earlier Calibration Results Sheet and where it came from (``source``: the
    earlier run's uid and sheet, as the rows' notes and "sheets used" cite it)."""

    sheet: CalibrationResults
    source: str

    def row(self, inst: str, par: str) -> ResultRow | None:
        """The earlier row, or None when that sheet did not determine it."""
        r = next((r for r in self.sheet.rows if r.instrument == inst and r.parameter == par),
                 None)
        return r if r is not None and r.estimate is not None else None


def _need(prior: PriorSheet, inst: str, par: str) -> ResultRow:
    r = prior.row(inst, par)
    if r is None or r.sigma is None:
        raise CheckFailed(f"{prior.source}: {inst} {par} is not determined there, and "
                          "this run does not measure it (Chart II-16)")
    return r


def prior_gyro(prior: PriorSheet, measured: set[int]
               ) -> dict[int, dict[int, tuple[float, float]]]:
    """[(G_k.B_j)/DeltaPhi] (pulses/deg) and its sigma for each pair (2j-1, 2j) not in
    ``measured``, from the earlier DeltaPhi (deg/pulse) and G.B_j."""
    out: dict[int, dict[int, tuple[float, float]]] = {}
    missing = [j for j in (1, 2, 3) if not {2 * j - 1, 2 * j} <= measured]
    if not missing:
        return out
    for k in (1, 2, 3):
        dp = _need(prior, f"gyro{k}", "DeltaPhi")
        d, sd = float(dp.estimate or 0.0), float(dp.sigma or 0.0)
        for j in missing:
            gb = _need(prior, f"gyro{k}", f"G.B{j}")
            g, sg = float(gb.estimate or 0.0), float(gb.sigma or 0.0)
            out.setdefault(k, {})[j] = (g / d, math.hypot(sg / d, g * sd / d**2))
    return out


def last_d1d3(prior: PriorSheet, accel_positions: set[int]
              ) -> tuple[dict[int, float], dict[int, float]]:
    """Step 7: the earlier D1 D3 ((pulses/s)/g^3) and its sigma of each accelerometer
    whose bisector position this run did not measure (and which the earlier sheet has)."""
    val: dict[int, float] = {}
    sig: dict[int, float] = {}
    for k, m in BISECTOR.items():
        if m in accel_positions:
            continue
        d1, d3 = prior.row(f"accel{k}", "D1"), prior.row(f"accel{k}", "D3")
        if d1 is None or d3 is None:
            continue
        a, b = float(d1.estimate or 0.0), float(d3.estimate or 0.0)
        val[k] = a * b
        sig[k] = math.hypot(b * (d1.sigma or 0.0), a * (d3.sigma or 0.0))
    return val, sig


def carry_rows(rows: list[ResultRow], prior: PriorSheet,
               supplied: dict[int, dict[int, tuple[float, float]]],
               d1d3: dict[int, float]) -> list[str]:
    """In place: every row the run did not determine takes the earlier row (estimate and
    sigma); a gyro's DeltaPhi and G.B_j computed only from supplied prerequisites are the
    earlier ones; rows computed with supplied prerequisites name them. Returns the rows
    carried ("gyro1 R", ...)."""
    carried = []
    for r in rows:
        k = int(r.instrument[-1])
        gyro = r.instrument.startswith("gyro")
        sup = supplied.get(k, {}) if gyro else {}
        from_prior = r.estimate is None or (
            gyro and ((r.parameter == "DeltaPhi" and len(sup) == 3)
                      or (r.parameter.startswith("G.B") and int(r.parameter[-1]) in sup)))
        old = prior.row(r.instrument, r.parameter)
        if from_prior and old is not None:
            r.estimate, r.sigma = old.estimate, old.sigma
            r.note = f"carried forward from {prior.source}"
            carried.append(f"{r.instrument} {r.parameter}")
        elif r.estimate is not None and gyro and sup:
            used = ", ".join(f"G.B{j}/DeltaPhi" for j in sorted(sup))
            r.note = _join(r.note, f"prerequisites {used} from {prior.source}")
        elif r.estimate is not None and not gyro and k in d1d3:
            r.note = _join(r.note, f"last (D1 D3) from {prior.source}")
    return carried


def _join(a: str, b: str) -> str:
    return f"{a}; {b}" if a else b
