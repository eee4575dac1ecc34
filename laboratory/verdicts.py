"""Verdicts: each result row judged against its acceptance limit, and the run's outcome.

A row gets ``limit`` (the number that decided it, or None), ``limit_text`` (the limit as
read, e.g. "|x - 3| <= 0.03 arcsec/pulse; sigma <= 0.0003") and ``verdict`` (PASS, FAIL or
NO LIMIT), which a real laboratory could give from its own figures (estimate, predicted
sigma, measured instability or rms). In simulation ``truth_check`` says whether the error
against the simulator's truth is within TRUTH_SIGMAS predicted sigma: a check of the
simulation and its error model, never part of the verdict. Limits: station/config/limits.py.
"""

from __future__ import annotations

from collections.abc import Iterable

from laboratory import identity
from station.config.limits import CigtfLimits, ConstantLimit, EsgLimits, IsuLimits

PASS, FAIL, NO_LIMIT = "PASS", "FAIL", "NO LIMIT"
TRUTH_SIGMAS = 4.0


def truth_check(errors: Iterable[float | None], sigmas: Iterable[float | None]) -> str | None:
    """'within 4 sigma' if every error is within TRUTH_SIGMAS of its sigma, 'beyond 4 sigma'
    if one is not; None without truth (a real or served laboratory) or without a sigma."""
    pairs = list(zip(errors, sigmas, strict=True))
    if not pairs or any(e is None or not s for e, s in pairs):
        return None
    inside = all(abs(e) <= TRUTH_SIGMAS * s for e, s in pairs if e is not None and s)
    return f"within {TRUTH_SIGMAS:g} sigma" if inside else f"beyond {TRUTH_SIGMAS:g} sigma"


def _num(x: float) -> str:
    return f"{x:.6g}"


def describe(lim: ConstantLimit, units: str) -> str:
    """The limit as a row prints it."""
    u = f" {units}" if units and units != "-" else ""
    parts = []
    if lim.max_abs is not None:
        c = lim.nominal or 0.0
        parts.append(f"|x - {_num(c)}| <= {_num(lim.max_abs)}{u}" if c
                     else f"|x| <= {_num(lim.max_abs)}{u}")
    if lim.interval is not None:
        parts.append(f"{_num(lim.interval[0])} <= x <= {_num(lim.interval[1])}{u}")
    if lim.max_sigma is not None:
        parts.append(f"sigma <= {_num(lim.max_sigma)}{u}")
    return "; ".join(parts)


def judge_constant(row: dict, lim: ConstantLimit | None) -> dict:
    """A Calibration Results row with its verdict (the row is changed and returned)."""
    row["truth_check"] = truth_check([row.get("error")], [row.get("sigma")])
    x, sigma = row.get("estimate"), row.get("sigma")
    if lim is None:
        row.update(limit=None, limit_text="no limit", verdict=NO_LIMIT)
        return row
    text = describe(lim, row.get("units", ""))
    row["limit"] = lim.max_abs if lim.max_abs is not None else lim.max_sigma
    if x is None:  # not determined (a partial day): nothing to judge
        row.update(limit_text=f"not determined ({text})", verdict=NO_LIMIT)
        return row
    ok = True
    if lim.max_abs is not None:
        ok &= abs(x - (lim.nominal or 0.0)) <= lim.max_abs
    if lim.interval is not None:
        ok &= lim.interval[0] <= x <= lim.interval[1]
    if lim.max_sigma is not None:
        ok &= sigma is not None and sigma <= lim.max_sigma
    row.update(limit_text=text, verdict=PASS if ok else FAIL)
    return row


def judge_constants(rows: list[dict], limits: IsuLimits) -> list[dict]:
    """Every row of results.json's ``calibration`` judged (in place; returned)."""
    for r in rows:
        judge_constant(r, limits.constant(r["instrument"], r["parameter"]))
    return rows


def judge_alignments(entries: list[dict], limits: IsuLimits) -> list[dict]:
    """Every alignment entry judged on its predicted sigma per axis (in place; returned);
    a skipped alignment has no verdict."""
    for e in entries:
        if "skipped" in e:
            continue
        sig = e["predicted_sigma_arcsec"]
        errors = [*e["level_error_arcsec"], e["azimuth_error_arcsec"]]
        e["truth_check"] = truth_check(errors, sig)
        lim = limits.alignment.get(e["method"])
        if lim is None:
            e.update(limit=None, limit_text="no limit", verdict=NO_LIMIT)
            continue
        m = lim.max_sigma_arcsec
        ok = all(s <= x for s, x in zip(sig, m, strict=True))
        e.update(limit=list(m), verdict=PASS if ok else FAIL,
                 limit_text=f"predicted sigma E/N/az <= {'/'.join(_num(x) for x in m)} arcsec")
    return entries


def judge_phases(phases: list[dict], truth_theta: float | None,
                 limits: CigtfLimits) -> list[dict]:
    """The CIGTF phase rows: the instability (delta, Delta) against its limit; in
    simulation, the phase theta against the truth of eq. 26."""
    names = {"operating": ("delta", limits.max_operating_instability_arcsec),
             "shutdown": ("Delta", limits.max_shutdown_instability_arcsec)}
    for p in phases:
        symbol, most = names[p["phase"]]
        p["truth_check"] = truth_check(
            [None if truth_theta is None else p["theta_arcsec"] - truth_theta],
            [p["sigma_arcsec"]])
        if most is None:
            p.update(limit=None, limit_text="no limit", verdict=NO_LIMIT)
            continue
        p.update(limit=most, limit_text=f"{symbol} <= {_num(most)} arcsec",
                 verdict=PASS if p["instability_arcsec"] <= most else FAIL)
    return phases


def judge_schedules(schedules: list[dict], limits: EsgLimits) -> list[dict]:
    """The ESG schedule rows: the measured readout rms against the goal. No truth check:
    the readout rms has no predicted sigma to hold the true error against."""
    most = limits.readout_rms_arcsec
    for s in schedules:
        s["truth_check"] = None
        if most is None:
            s.update(limit=None, limit_text="no limit", verdict=NO_LIMIT)
            continue
        s.update(limit=most, limit_text=f"readout rms <= {_num(most)} arcsec",
                 verdict=PASS if s["readout_rms_arcsec"] <= most else FAIL)
    return schedules


def label(row: dict) -> str:
    """How a row is named in the run's list of failures."""
    if "instrument" in row:
        return f"{row['instrument']}.{row['parameter']}"
    if "method" in row:
        return f"{row['method']}/{row['estimator']} alignment"
    if "phase" in row:
        return f"{row['phase']} phase"
    return f"schedule {row['name']}"


def run_verdict(*groups: Iterable[dict]) -> dict:
    """The run's outcome: FAIL if a row failed, else PASS if a row passed, else NO LIMITS;
    ``failed`` lists the failed rows' labels."""
    rows = [r for g in groups for r in g if "verdict" in r]
    failed = [label(r) for r in rows if r["verdict"] == FAIL]
    outcome = FAIL if failed else PASS if any(r["verdict"] == PASS for r in rows) \
        else "NO LIMITS"
    ident = identity.current()
    if ident is not None:  # run.json carries the verdict (and exit 3 for a FAIL)
        ident.verdict = outcome
    return {"outcome": outcome, "failed": failed}
