"""Counter outputs to the rates the calibration equations use (the "special routine" of II-4.2
and II-4.3): each term (Sigma delta)/(Sigma n1^T) or (Sigma gamma)/(Sigma n1^T), over S1^T.

Keys (kind, k, m):
* ("w", 0, m): table rate over the whole turns of position m = 1..6, deg/s,
  S^phi (Sigma n^phi) / ((Sigma n1^T) S1^T);
* ("G", k, m): gyro k's pulse rate at position m, pulses/s, (Sigma delta) / ((Sigma n1^T) S1^T);
* ("F", k, m): accelerometer k's f2 - f1 at position m (7-15; 16 on: the extra positions,
  ``reduce_all``), pulses/s, each string's
  (Sigma gamma) / ((Sigma n1^T) S1^T) counted separately;
* ("X", k, 0): the supplied last (D1 D3) of accelerometer k (Chart II-15 step 7);
* ("P", k, j): a supplied [(G_k.B_j)/DeltaPhi], pulses/deg, from an earlier sheet (the
  prerequisite of a partial calibration when pair 2j-1, 2j was not measured).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from procedures.isu.calibration.inputs import TURNING_POSITIONS, AccelPosition, CalibrationData

Key = tuple[str, int, int]


@dataclass(frozen=True)
class Record:
    """What the error model needs to know about one reduced datum."""

    key: Key
    t0: float = 0.0
    length: float = 0.0  # gate, s
    n1: float = 0.0  # clock ticks of the gate (gyro and table-rate data)
    strings: tuple[tuple[float, float, float], ...] = ()  # (f, n1, gate s) of strings 1, 2
    t_level: float = 0.0
    sigma: float = 0.0  # supplied data only
    pulse_gate: bool = False  # a gyro's gate of preset pulses (II-5.2): n1 is its clock count


@dataclass
class Reduced:
    values: dict[Key, float] = field(default_factory=dict)
    records: dict[Key, Record] = field(default_factory=dict)

    def add(self, rec: Record, value: float) -> None:
        self.values[rec.key] = float(value)
        self.records[rec.key] = rec


def reduce(data: CalibrationData) -> Reduced:
    """Every counter output of the data as its rate, keyed as the module says."""
    s1 = data.constants.s1_t
    out = Reduced()
    for m, gp in sorted(data.gyro.items()):
        t = gp.n1 * s1
        # the gate ends at the print-out; it may open after the switch to operate (positions
        # 1-6 wait for the next rotation pulse), so it is placed against t1 when t1 allows
        start = max(gp.t0, gp.t1 - t)
        if m in TURNING_POSITIONS:
            if gp.n_phi is None:  # CalibrationData's validator refuses this already
                raise ValueError(f"gyro position {m} needs n_phi (rotation pulses)")
            rec = Record(("w", 0, m), start, t, gp.n1)
            out.add(rec, data.constants.s_phi * float(gp.n_phi) / t)
        for k in (1, 2, 3):
            if gp.n1_each is None:
                out.add(Record(("G", k, m), start, t, gp.n1), gp.delta[k - 1] / t)
                continue
            # II-5.2's pulse gate: each gyro's own gate, opened on its first pulse after
            # the switch to operate (placed at the switch: within one pulse period)
            n1 = gp.n1_each[k - 1]
            rec = Record(("G", k, m), gp.t0, n1 * s1, n1, pulse_gate=gp.pulse_gated[k - 1])
            out.add(rec, gp.delta[k - 1] / (n1 * s1))
    for m, p in sorted(data.accel.items()):
        _accel(out, m, p, s1)
    for k, x in sorted(data.last_d1d3.items()):
        out.add(Record(("X", k, 0), sigma=data.last_d1d3_sigma.get(k, 0.0)), x)
    for k, js in sorted(data.prior_gyro.items()):
        for j, (v, sig) in sorted(js.items()):
            out.add(Record(("P", k, j), sigma=sig), v)
    return out


def _accel(out: Reduced, m: int, p: AccelPosition, s1: float) -> None:
    """Each accelerometer's f2 - f1 at position m, its strings counted separately."""
    for k in (1, 2, 3):
        if (k, 1) not in p.gamma or (k, 2) not in p.gamma:
            continue
        strings = []
        for ell in (1, 2):
            n1 = p.n1[(k, ell)]
            strings.append((p.gamma[(k, ell)] / (n1 * s1), n1, n1 * s1))
        rec = Record(
            ("F", k, m), p.t0, max(s[2] for s in strings), 0.0, tuple(strings), p.t_level
        )
        out.add(rec, strings[1][0] - strings[0][0])


def reduce_all(data: CalibrationData) -> Reduced:
    """``reduce`` plus the extra accelerometer positions (m >= 16, beyond the manual), which
    only the all-positions fit takes."""
    out = reduce(data)
    for m, p in sorted(data.extra_accel.items()):
        _accel(out, m, p, data.constants.s1_t)
    return out
