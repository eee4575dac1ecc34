"""A rehearsal against its virtual twin: what "the same sheets" means across real time.

The twin is the same procedure, config and seed run in virtual time from the simulated
instant the rehearsal began (``station day --start-at T``). The real-time clock changes
two things, and only those (docs/hil.md, "Time quantization"):

* every exchange with the served rack lands at the simulated instant its bytes arrive,
  so each wall second spent outside the simulation (round trips, parsing, journal
  flushes) becomes ``speed`` simulated seconds: the rehearsal's timeline runs later than
  the twin's by the accumulated overhead, never earlier;
* readings are therefore taken at other simulated instants, and instruments whose
  noise is drawn per reading draw in another order (a search that needs one more try
  shifts every later draw): measured values agree within their noise, not bit for bit.

So the comparison is exact for the structure (sheets, charts, step numbers and texts, in
order) and for everything set rather than measured (counter settings and connections,
the site's g and Earth rate), bounded for times, and within noise for measurements:
counter outputs (gyro net pulses, accelerometer clock counts), the survey's T^BI and the
calibration estimates (within k sqrt(2) sigma of each other: both carry the predicted
error sigma). Per-step readings feed those results and are not compared one by one.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Tolerances:
    late_fraction: float = 0.25  # rehearsal may run late by this much of the elapsed time
    late_slack_s: float = 30.0  # plus this (the first exchanges, one journal flush)
    early_s: float = 1.0  # it may not run earlier than the twin by more than this
    # lateness is the machine's: its load and speed set how far the served rack runs ahead
    # of a client that computes (tests compare the record without it: no wall-clock
    # assertion); `station compare --rehearsal` keeps it, to tell a rehearsal that fell behind
    check_late: bool = True
    # net pulses of a 600 s gate: ARW 0.003 deg/rt-h is 1.5 pulses of 3 arcsec, the
    # quantization 0.6, the drift process 0.6: sigma 1.7 per reading, 2.4 for the
    # difference of two; 5 sigma. (Twenty seeds shifted by 400 s: std 1.8, max 5.)
    gyro_counts: int = 12
    clock_count_rel: float = 2e-6  # accelerometer clock counts (level-correction noise)
    t_bi: float = 2e-5  # survey direction cosines (autocollimator noise ~1 arcsec)
    sigma_k: float = 4.0  # calibration estimates: |difference| <= k sqrt(2) sigma


def _sheets(d: Path) -> dict[str, dict]:
    return {f.stem: json.loads(f.read_text()) for f in sorted((d / "sheets").glob("*.json"))}


def _start(d: Path) -> float:
    with open(d / "journal.jsonl", encoding="utf-8") as f:
        for line in f:
            rec = json.loads(line)
            if rec.get("event") == "start":
                return float(rec["t_sim"])
    raise ValueError(f"{d}/journal.jsonl has no start record")


def compare_rehearsal(rehearsal: Path, twin: Path, tol: Tolerances = Tolerances()
                      ) -> list[str]:
    """What differs beyond the tolerances (empty: the rehearsal saw what the twin saw)."""
    a, b = _sheets(Path(rehearsal)), _sheets(Path(twin))
    out: list[str] = []
    if set(a) != set(b):
        return [f"sheets differ: only in rehearsal {sorted(set(a) - set(b))}, "
                f"only in twin {sorted(set(b) - set(a))}"]
    t0 = _start(Path(twin))
    for name in sorted(n for n in a if n.startswith("check_")):
        out += _check_sheet(name, a[name], b[name], t0, tol)
    for name in ("counter_settings", "counter_connections"):
        if name in a and a[name] != b[name]:
            out.append(f"{name}: set values differ")
    if "counter_outputs" in a:
        out += _counts(a["counter_outputs"]["outputs"], b["counter_outputs"]["outputs"], tol)
    if "survey_results" in a:
        out += _survey(a["survey_results"], b["survey_results"], tol)
    if "calibration_results" in a:
        out += _calibration(a["calibration_results"], b["calibration_results"], tol)
    return out


def _check_sheet(name: str, a: dict, b: dict, t0: float, tol: Tolerances) -> list[str]:
    sa = [(s["number"], s["text"]) for s in a["steps"]]
    sb = [(s["number"], s["text"]) for s in b["steps"]]
    if sa != sb:
        return [f"{name}: steps differ ({len(sa)} against {len(sb)})"]
    out = []
    for x, y in zip(a["steps"], b["steps"], strict=True):
        late = x["t_sim"] - y["t_sim"]
        bound = tol.late_fraction * (y["t_sim"] - t0) + tol.late_slack_s
        if late < -tol.early_s or (tol.check_late and late > bound):
            out.append(f"{name} step {x['number']}: {late:+.2f} s from the twin "
                       f"(allowed {-tol.early_s:g} .. {bound:.1f} s)")
    return out


def _counts(a: dict, b: dict, tol: Tolerances) -> list[str]:
    if set(a) != set(b) or any(set(a[k]) != set(b[k]) for k in a):
        return ["counter_outputs: different rows or counters"]
    out = []
    for row in sorted(a):
        for c in sorted(a[row]):
            x, y = int(a[row][c]), int(b[row][c])
            allowed = (tol.gyro_counts if row.startswith("gyro")
                       else tol.clock_count_rel * max(abs(x), abs(y)))
            if abs(x - y) > allowed:
                out.append(f"counter_outputs {row} counter {c}: {x} against {y} "
                           f"(allowed +-{allowed:.0f})")
    return out


def _survey(a: dict, b: dict, tol: Tolerances) -> list[str]:
    out = []
    for k in ("g", "omega_sin_lambda_deg_hr", "omega_cos_lambda_deg_hr"):
        if a[k] != b[k]:
            out.append(f"survey_results {k}: {a[k]} against {b[k]} (entered, not measured)")
    worst = max(abs(x - y) for ra, rb in zip(a["t_bi"], b["t_bi"], strict=True)
                for x, y in zip(ra, rb, strict=True))
    if worst > tol.t_bi:
        out.append(f"survey_results t_bi: differs by {worst:.2e} (allowed {tol.t_bi:g})")
    return out


def _calibration(a: dict, b: dict, tol: Tolerances) -> list[str]:
    out = []
    ra = {(r["instrument"], r["parameter"]): r for r in a["rows"]}
    rb = {(r["instrument"], r["parameter"]): r for r in b["rows"]}
    if set(ra) != set(rb) or a["positions_used"] != b["positions_used"]:
        return ["calibration_results: different rows or positions"]
    for k in sorted(ra):
        x, y = ra[k]["estimate"], rb[k]["estimate"]
        if (x is None) != (y is None):
            out.append(f"calibration {k}: determined in one run only")
        elif x is not None:
            s = max(ra[k]["sigma"] or 0.0, rb[k]["sigma"] or 0.0)
            if abs(x - y) > tol.sigma_k * math.sqrt(2.0) * s:
                out.append(f"calibration {k}: {x:.6g} against {y:.6g} (sigma {s:.2g})")
    return out
