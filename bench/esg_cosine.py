"""A cosine-pattern rotor against the report's great circle (docs/esg-options.md): over
seeds, the true calibration and readout rms of both schedules and the points refused as
mis-gated.

    python bench/esg_cosine.py [n_seeds] [top_colatitude_deg]
"""

from __future__ import annotations

import json
import tempfile
from dataclasses import replace
from pathlib import Path

from _args import count, parser

from laboratory.esg.calibration import run_esg_calibration
from sim.esg import EsgParams
from sim.esg.pattern import PatternSpec


def one(seed: int, spec: PatternSpec) -> dict:
    """One calibration's figures."""
    with tempfile.TemporaryDirectory() as d:
        res = run_esg_calibration(seed, Path(d), params=replace(EsgParams(), pattern=spec),
                                  with_study=False)
        refused = sum('"refused"' in line for line in
                      (Path(d) / "journal.jsonl").read_text().splitlines()
                      if json.loads(line).get("kind") == "step")
    out = {"sim_h": res["sim_seconds"] / 3600.0, "refused": float(refused)}
    for s in res["schedules"]:
        out[f"{s['name']} cal"] = s["true_calibration_rms_arcsec"]
        out[f"{s['name']} readout"] = s["true_readout_rms_arcsec"]
    return out


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__)
    ap.add_argument("n", metavar="n_seeds", nargs="?", type=count, default=4,
                    help="seeds 1..n_seeds (default 4)")
    ap.add_argument("top", metavar="top_colatitude_deg", nargs="?", type=float, default=37.0,
                    help="the cosine pattern's top colatitude, degrees (default 37)")
    a = ap.parse_args(argv)
    n, top = a.n, a.top
    for spec in (PatternSpec(), PatternSpec(kind="cosine", top_colatitude_deg=top)):
        rows = [one(seed, spec) for seed in range(1, n + 1)]
        mean = {k: sum(r[k] for r in rows) / n for k in rows[0]}
        worst = max(r["1-2-5deg readout"] for r in rows)
        print(f"{spec.kind} {spec.top_colatitude_deg:g}: "
              + ", ".join(f"{k} {v:.1f}" for k, v in mean.items())
              + f", worst 1-2-5deg readout {worst:.1f}")


if __name__ == "__main__":
    main()
