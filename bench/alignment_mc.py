"""Are the alignments' predicted sigmas honest, and does the posterior mean beat the average?

For each seed: (a) a calibration day followed by the three alignments (what `station day`
records: level and gyrocompass each processed by both techniques); (b) on a fresh rack, the
level and gyrocompass alignments again with the simulator's true calibration constants, so
that only the estimation error is left (the calibration error is common to both techniques
and would hide their difference). Prints, per method and technique, the observed rms error
about east, north and up against the mean predicted sigma, their ratio and the largest
|error|/sigma, the mean physical limit; then the estimation-only rms of the average and of
the posterior mean on the same records against the estimator's predicted sigma.

    python bench/alignment_mc.py [N] [first_seed]     (default 20 seeds from 3000)

Kept as a script for its paired runs, which a campaign's independent tasks do not express;
the per-seed errors against the predicted sigma are the campaign bench/campaigns/alignment.toml.
"""

from __future__ import annotations

import json
import statistics
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from _args import parser, seeds


def one(seed: int) -> dict:
    from laboratory.isu.align import alignment_entries, day_alignments
    from laboratory.isu.spec import noise_spec, site_of
    from laboratory.isu.truth import calibration_truth
    from procedures.isu.alignment.options import AlignmentOptions
    from procedures.isu.alignment.run import run_alignments
    from procedures.isu.computations import compute_calibration
    from procedures.isu.day import measure_day
    from procedures.isu.plan import DayPlan
    from procedures.isu.turn_on import turn_on
    from procedures.journal import Journal
    from procedures.runner import Run
    from station.config.isu import load_config
    from station.racks.isu import SimulatedRack, open_isu_drivers

    cfg = load_config(seed=seed)
    out: dict = {"seed": seed}
    with tempfile.TemporaryDirectory() as d:
        rack = SimulatedRack(cfg)
        st = open_isu_drivers(cfg, rack)
        try:
            run = Run(st.clock, Journal(Path(d) / "day.jsonl"))
            plan = DayPlan()
            site = site_of(cfg)
            data = measure_day(st, run, plan, site, cfg.isu.accels[0].f0_hz)
            calib = compute_calibration(run, data, plan, noise_spec(cfg),
                                        site)
            out["day"] = day_alignments(st, run, calib, cfg, rack.world)
            truth = calibration_truth(rack.world)
            exact = calib.model_copy(deep=True)
            for r in exact.rows:
                r.estimate = truth[(r.instrument, r.parameter)]
            survey = data.survey
        finally:
            st.close()
            rack.close()
        rack = SimulatedRack(cfg)
        st = open_isu_drivers(cfg, rack)
        try:
            run = Run(st.clock, Journal(Path(d) / "exact.jsonl"))
            turn_on(st, run, 1800.0)
            oc = run_alignments(st, run, AlignmentOptions(
                noise_spec(cfg), exact, survey, site_of(cfg),
                estimators={"level": ("average", "posterior"),
                            "gyrocompass": ("average", "hybrid")}))
            ents = alignment_entries(oc, rack.world)
            for e, o in zip(ents, oc, strict=True):
                e["parts"] = o.detail["parts"]
            out["exact"] = ents
        finally:
            st.close()
            rack.close()
    return out


def rms(xs) -> float:
    return (sum(x * x for x in xs) / len(xs)) ** 0.5


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__)
    seeds(ap, 20, 3000)
    a = ap.parse_args(argv)
    n, first = a.n, a.first
    with ProcessPoolExecutor(max_workers=2) as ex:
        runs = list(ex.map(one, range(first, first + n)))
    print(f"{n} seeds from {first}: errors against the true attitude at t_ref (arcsec)")
    print(f"{'method':12} {'technique':10} {'axis':5} {'rms err':>8} {'mean sig':>8} "
          f"{'ratio':>6} {'max|z|':>7} {'limit':>7} {'sig/lim':>7}")
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in runs:
        for e in r["day"]:
            groups.setdefault((e["method"], e["estimator"]), []).append(e)
    for (m, est), es in groups.items():
        for i, ax in enumerate(("E", "N", "az")):
            errs = [(e["level_error_arcsec"] + [e["azimuth_error_arcsec"]])[i] for e in es]
            sig = statistics.mean(e["predicted_sigma_arcsec"][i] for e in es)
            lim = statistics.mean(e["physical_limit_arcsec"][i] for e in es)
            z = max(abs(e["error_over_sigma"][i]) for e in es)
            print(f"{m:12} {est:10} {ax:5} {rms(errs):8.3f} {sig:8.3f} "
                  f"{rms(errs) / sig:6.2f} {z:7.2f} {lim:7.3f} {sig / lim:7.2f}")
    print("\nEstimation only (true calibration constants; both techniques on the same records)")
    print(f"{'method':12} {'technique':10} {'axis':5} {'rms err':>8} {'predicted':>9}")
    ex_groups: dict[tuple[str, str], list[dict]] = {}
    for r in runs:
        for e in r["exact"]:
            ex_groups.setdefault((e["method"], e["estimator"]), []).append(e)
    for (m, est), es in ex_groups.items():
        key = "estimator" if m == "level" else "estimator_g"
        for i, ax in enumerate(("E", "N")):
            errs = [e["level_error_arcsec"][i] for e in es]
            pred = rms([e["parts"][key][i] for e in es])
            print(f"{m:12} {est:10} {ax:5} {rms(errs):8.3f} {pred:9.3f}")
    lv = {est: [x for e in es for x in e["level_error_arcsec"]]
          for (m, est), es in ex_groups.items() if m == "level"}
    if {"average", "posterior"} <= set(lv):
        a, p = rms(lv["average"]), rms(lv["posterior"])
        k = len(lv["average"])
        print(f"\nlevel, both axes, {k} values: average {a:.3f} arcsec rms, posterior mean "
              f"{p:.3f} (ratio {p / a:.2f}; sampling spread of each about "
              f"{100 / (2 * k) ** 0.5:.0f} %)")
    for r in runs:  # keep the record small: errors, sigmas and limits, not the matrices
        for e in r["day"] + r["exact"]:
            e.pop("T", None)
            e.pop("T_true", None)
            if "parts" in e:
                e["parts"] = {k: v for k, v in e["parts"].items()
                              if k in ("estimator", "estimator_g")}
    Path("bench/alignment_mc.json").write_text(json.dumps(runs, separators=(",", ":")))


if __name__ == "__main__":
    main()
