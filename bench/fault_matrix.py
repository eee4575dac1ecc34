"""Run calibration days with every fault kind of docs/faults.md and count what became of them.

    python bench/fault_matrix.py [--seeds N] [--first-seed S] [--jobs J] [--timeout SEC]
                                 [--only KIND] [--cases issue|matrix|all] [--json FILE]

Each day is ``station day`` (virtual time, alignments included) in its own subprocess with
a ``[faults.<instrument>]`` table, so a hang is a per-day timeout and an escaped exception
a traceback on stderr. Every outcome is judged against the fault-free day of the same seed:

* identical: exit 0 and every constant, sigma and alignment T equal to the fault-free day's;
* within 4 sigma: exit 0, every calibration constant and alignment within 4 of its
  predicted sigma of the truth (the fault-free day's own beyond-4-sigma rows excused);
* stopped, named: exit 1 with a stop naming the chart and step, and naming the faulted
  instrument (or, for a stalled axis, the table and the axis);
* stopped, misleading: exit 1 but the stop names neither;
* silent: exit 0 with a constant or alignment beyond 4 sigma the fault-free day did not have;
* traceback: any other exit, or a Python traceback in the output;
* hang: no exit within the per-day timeout.

Fault kinds and their three rates: latency_s, drop_rate, corrupt_rate (serial bytes; IEU
frames), silent_after_s (three times into the day), stall_axis (the four axes, stalling at
three times: under a turning gate, during the J-term ramps, in the static positions). The
issue's two cases run too (``--cases issue``): bubble-level
``drop_rate = 0.001`` on seed 1970 and IEU ``corrupt_rate = 3e-4`` on six seeds.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from _args import count, parser, positive

ROOT = Path(__file__).resolve().parents[1]
Z_LIMIT = 4.0
OUTCOMES = ("identical", "within 4 sigma", "stopped, named", "stopped, misleading",
            "silent beyond 4 sigma", "traceback", "hang")

SERIAL = ("table", "counter1", "counter3", "bubble_levels", "autocollimator1", "patch_panel",
          "oscillator")
RATES = {
    "latency_s": {"serial": (0.05, 0.5, 6.0), "ieu": (0.01, 0.5, 6.0)},
    "drop_rate": {"serial": (1e-4, 1e-3, 1e-2), "ieu": (1e-4, 1e-3, 1e-2)},
    "corrupt_rate": {"serial": (1e-4, 1e-3, 1e-2), "ieu": (3e-5, 3e-4, 3e-3)},
    "silent_after_s": {"serial": (600.0, 12000.0, 30000.0), "ieu": (600.0, 30000.0, 32500.0)},
}
# inside the turning positions' first gate (II-6), during the J-term ramps (II-10), in the
# static positions (II-13)
STALL_TIMES = (2100.0, 11800.0, 20000.0)


@dataclass
class Case:
    kind: str  # the fault field
    instrument: str
    rate: float
    seed: int
    faults: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        return f"{self.kind} {self.instrument} {self.rate:g} seed {self.seed}"


def matrix_cases(seeds: list[int]) -> list[Case]:
    out = []
    for kind, rates in RATES.items():
        for inst in (*SERIAL, "ieu"):
            for rate in rates["ieu" if inst == "ieu" else "serial"]:
                for s in seeds:
                    out.append(Case(kind, inst, rate, s, {inst: {kind: rate}}))
    for axis in (1, 2, 3, 4):
        for t in STALL_TIMES:
            for s in seeds:
                out.append(Case("stall_axis", f"table axis {axis}", t, s,
                                {"table": {"stall_axis": axis, "stall_after_s": t}}))
    return out


def issue_cases() -> list[Case]:
    out = [Case("drop_rate", "bubble_levels", 1e-3, 1970, {"bubble_levels": {"drop_rate": 1e-3}})]
    out += [Case("corrupt_rate", "ieu", 3e-4, s, {"ieu": {"corrupt_rate": 3e-4}})
            for s in range(1, 7)]
    return out


def toml(faults: dict) -> str:
    lines = []
    for inst, spec in faults.items():
        lines.append(f"[faults.{inst}]")
        lines += [f"{k} = {v!r}" for k, v in spec.items()]
    return "\n".join(lines) + "\n"


def run_day(faults: dict, seed: int, timeout: float) -> dict:
    """One `station day` in a subprocess; what it left behind."""
    with tempfile.TemporaryDirectory(prefix="fault_matrix_") as d:
        cfg = Path(d) / "faults.toml"
        cfg.write_text(toml(faults))
        out = Path(d) / "run"
        cmd = [sys.executable, "-m", "laboratory.cli", "day", "--config", str(cfg), "--seed",
               str(seed), "--out", str(out), "--quiet"]
        env = {**os.environ, "COLUMNS": "400", "PYTHONHASHSEED": "0"}
        w0 = time.perf_counter()
        try:
            p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=timeout,
                               env=env)
        except subprocess.TimeoutExpired:
            return {"hang": True, "wall": time.perf_counter() - w0}
        res = {"hang": False, "rc": p.returncode, "stdout": p.stdout, "stderr": p.stderr,
               "wall": time.perf_counter() - w0}
        if (out / "results.json").exists():
            res["results"] = json.loads((out / "results.json").read_text())
        jpath = out / "journal.jsonl"
        if jpath.exists():
            recs = [json.loads(x) for x in jpath.read_text().splitlines() if x.strip()]
            failed = [r for r in recs if r.get("kind") == "failed"]
            res["failed"] = failed[-1] if failed else None
        return res


def z_scores(results: dict) -> dict[str, float]:
    """|error| / sigma of every constant and alignment angle against the truth."""
    out = {}
    for r in results.get("calibration", []):
        if r["error"] is not None and r["sigma"]:
            out[f"{r['instrument']} {r['parameter']}"] = abs(r["error"] / r["sigma"])
    for a in results.get("alignment", []):
        for axis, z in zip(("east", "north", "up"), a["error_over_sigma"], strict=True):
            out[f"{a['method']} {a['estimator']} about {axis}"] = abs(z)
    return out


def fingerprint(results: dict) -> str:
    cal = [(r["instrument"], r["parameter"], r["estimate"], r["sigma"])
           for r in results.get("calibration", [])]
    ali = [(a["method"], a["estimator"], a["T"]) for a in results.get("alignment", [])]
    return json.dumps([cal, ali])


def names_cause(case: Case, step: str, cause: str) -> bool:
    """The stop names the chart and step, and its cause (not the step's own text) names the
    faulted instrument (a stall: the table and its axis)."""
    if not step:
        return False
    if case.kind == "stall_axis":
        axis = case.instrument.split()[-1]
        return "table" in cause and f"axis {axis}" in cause
    return case.instrument.lower() in cause.lower()


def stop_message(res: dict) -> tuple[str, str]:
    """(chart and step, cause) of a stopped day: the journal's failed step, else the CLI's
    "stopped:" line (a stop outside any step names no step)."""
    if res.get("failed"):
        f = res["failed"]
        return f"Chart {f['chart']}, step {f['step']} ({f['text']})", f["error"]
    text = res.get("stdout", "")
    i = text.find("stopped:")
    return "", " ".join(text[i:].split()) if i >= 0 else text.strip()[-400:]


def classify(case: Case, res: dict, clean: dict) -> tuple[str, str]:
    """(outcome, detail) of a faulted day against the fault-free day of its seed."""
    if res["hang"]:
        return "hang", f"no exit within the timeout ({res['wall']:.0f} s)"
    out = res["stdout"] + res["stderr"]
    if "Traceback" in out or res["rc"] not in (0, 1):
        tail = out.strip().splitlines()[-1:] or [""]
        return "traceback", f"exit {res['rc']}: {tail[0][:300]}"
    if res["rc"] == 1:
        step, cause = stop_message(res)
        named = names_cause(case, step, cause)
        return ("stopped, named" if named else "stopped, misleading"), f"{step}: {cause}"
    results = res.get("results") or {}
    if clean.get("results") and fingerprint(results) == fingerprint(clean["results"]):
        return "identical", ""
    excused = {k for k, z in z_scores(clean.get("results") or {}).items() if z > Z_LIMIT}
    beyond = {k: z for k, z in z_scores(results).items() if z > Z_LIMIT and k not in excused}
    if beyond:
        worst = max(beyond, key=lambda k: beyond[k])
        return "silent beyond 4 sigma", (f"{len(beyond)} beyond 4 sigma, worst {worst} "
                                         f"{beyond[worst]:.1f} sigma")
    return "within 4 sigma", ""


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("--seeds", metavar="N", type=count, default=1,
                    help="seeds per matrix cell (default 1)")
    ap.add_argument("--first-seed", metavar="S", type=int, default=1, help="(default 1)")
    ap.add_argument("--jobs", metavar="J", type=count, default=2,
                    help="days run at once (default 2)")
    ap.add_argument("--timeout", metavar="SEC", type=positive, default=300.0,
                    help="per day, wall seconds (default 300)")
    ap.add_argument("--only", metavar="KIND", default="",
                    help="only fault kinds/instruments containing this")
    ap.add_argument("--cases", choices=("issue", "matrix", "all"), default="all")
    ap.add_argument("--json", metavar="FILE", type=Path, default=None,
                    help="write every outcome here")
    args = ap.parse_args(argv)
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    cases: list[Case] = []
    if args.cases in ("matrix", "all"):
        cases += matrix_cases(seeds)
    if args.cases in ("issue", "all"):
        cases += issue_cases()
    cases = [c for c in cases if args.only in c.label]
    w0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=args.jobs) as ex:
        clean_seeds = sorted({c.seed for c in cases})
        cleans = dict(zip(clean_seeds, ex.map(lambda s: run_day({}, s, args.timeout),
                                              clean_seeds), strict=True))
        for s, r in cleans.items():
            if r.get("hang") or r.get("rc") != 0:
                print(f"fault-free day of seed {s} did not complete: {stop_message(r)}")
                return 2
        results = list(ex.map(lambda c: run_day(c.faults, c.seed, args.timeout), cases))
    rows = []
    table: dict[tuple[str, str, float], Counter] = {}
    for c, r in zip(cases, results, strict=True):
        outcome, detail = classify(c, r, cleans[c.seed])
        inst = "table" if c.kind == "stall_axis" else c.instrument
        table.setdefault((c.kind, inst, c.rate), Counter())[outcome] += 1
        rows.append({"case": c.label, "faults": c.faults, "seed": c.seed, "outcome": outcome,
                     "detail": detail, "wall_s": r.get("wall")})
    short = ("ident", "<4sig", "named", "mislead", "silent", "trace", "hang")
    print(f"{'fault':15} {'instrument':16} {'rate':>8}  " + " ".join(f"{s:>7}" for s in short))
    for (kind, inst, rate), cnt in sorted(table.items()):
        print(f"{kind:15} {inst:16} {rate:8g}  "
              + " ".join(f"{cnt.get(o, 0):7d}" for o in OUTCOMES))
    total = Counter(r["outcome"] for r in rows)
    print(f"\n{len(rows)} faulted days over seeds {clean_seeds} in "
          f"{time.perf_counter() - w0:.0f} s wall:")
    for o in OUTCOMES:
        print(f"  {o:22} {total.get(o, 0)}")
    bad = [r for r in rows if r["outcome"] in OUTCOMES[3:]]
    for r in bad:
        print(f"  ! {r['outcome']}: {r['case']}: {r['detail'][:400]}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
