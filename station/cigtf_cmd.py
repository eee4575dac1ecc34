"""`station gyrocompass-test`: the CIGTF gyrocompassing accuracy test (report 001) in
virtual time, its journal, sheets (run table, phase table, conclusions), gyrocompass.json
and a plot of theta per run.

With ``links`` (``--links DIR``) the same procedure and drivers run against a rack served
by ``station serve --station cigtf --links DIR``, over its ptys and on a WallClock on the
rack's time. The truth (eq. 26) comes from a rack built here with the run's seed and
params and never run; it is left out (None) unless the served session has that seed and
config digest."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

from procedures.gyrocompass_test.analysis import phase_values, run_values
from procedures.gyrocompass_test.procedure import TestData, TestPlan, gyrocompass_test
from procedures.gyrocompass_test.significance import TestOutcome, judge
from sim.cigtf_world import CigtfParams
from station.cigtf_rack import CigtfRack, open_cigtf_station
from station.connect import connect_rack, journaled_run
from station.hil.session import params_digest
from station.record import write_sheets

PHASES = ("operating", "shutdown")


def _test(name: str, t: TestOutcome) -> dict:
    return {"name": name, "statistic": t.statistic, "threshold": t.threshold,
            "dof": list(t.dof), "significant": t.significant}


def theta_plot(res: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4))
    n = 0
    for ph, colour in zip(PHASES, ("tab:blue", "tab:orange"), strict=True):
        rows = [r for r in res["runs"] if r["phase"] == ph]
        x = list(range(n + 1, n + len(rows) + 1))
        n += len(rows)
        ax.errorbar(x, [r["theta_arcsec"] for r in rows], [r["sigma_arcsec"] for r in rows],
                    fmt="o", color=colour, capsize=2, label=f"{ph} runs")
        p = next((q for q in res["phases"] if q["phase"] == ph), None)
        if p is not None and x:
            ax.hlines(p["theta_arcsec"], x[0], x[-1], colors=colour, linestyles="--")
    if res["truth"]["theta_arcsec"] is not None:
        ax.axhline(res["truth"]["theta_arcsec"], color="k", lw=0.8, label="truth (eq. 26)")
    ax.set_xlabel("run")
    ax.set_ylabel("gyrocompassing error theta (arcsec)")
    ax.set_title("CIGTF gyrocompassing accuracy test")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def analyse(data: TestData) -> tuple[list[dict], list[dict], list[dict], dict]:
    """Section 5: run table, phase table, significance tests and conclusions of a test."""
    runs = [{"phase": ph, "run": i, "theta_arcsec": r.theta, "sigma_arcsec": r.sigma}
            for ph in PHASES for i, r in enumerate(data.runs[ph], start=1)]
    pv = {ph: phase_values(data.runs[ph]) for ph in PHASES}
    phases = [{"phase": ph, "theta_arcsec": p.theta, "sigma_arcsec": p.sigma,
               "s_arcsec": p.s, "n": p.n, "instability_arcsec": p.instability}
              for ph, p in pv.items()]
    rep = judge(pv["operating"], pv["shutdown"])
    tests = [
        _test("5.4.2 operating F (delta^2 / s1^2)", rep.operating.noise_test),
        _test("5.4.1 operating t |theta1 / se|", rep.operating.mean_test),
        _test("5.4.3 shutdown F (Delta^2 / s2^2)", rep.shutdown.noise_test),
        _test("5.4.1 shutdown t |theta2 / se|", rep.shutdown.mean_test),
        _test("5.4.4 shutdown vs operating F (Delta^2 / delta^2)", rep.shutdown_test),
    ]
    conclusions = {
        "gsf_arcsec_per_ma": data.gsf,
        "operating": {"theta_arcsec": pv["operating"].theta,
                      "standard_error_arcsec": rep.operating.standard_error,
                      "bias_significant": rep.operating.mean_test.significant,
                      "instability_exceeds_noise": rep.operating.noise_test.significant},
        "shutdown": {"theta_arcsec": pv["shutdown"].theta,
                     "standard_error_arcsec": rep.shutdown.standard_error,
                     "bias_significant": rep.shutdown.mean_test.significant,
                     "instability_exceeds_noise": rep.shutdown.noise_test.significant},
        "operating_instability_arcsec": pv["operating"].instability,
        "shutdown_instability_arcsec": pv["shutdown"].instability,
        "shutdown_adds_instability": rep.shutdown_test.significant,
    }
    return runs, phases, tests, conclusions


def data_from_journal(path: Path) -> tuple[TestData, int | None]:
    """Rebuild the test data from a journal: every completed run (its step 5.2 recorded)."""
    data = TestData()
    seed = None
    currents: dict[str, dict[int, list[float]]] = {}
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            break  # a record cut by a kill ends the usable journal
        if rec.get("kind") == "note" and rec.get("event") == "start":
            seed = rec.get("seed")
        if rec.get("kind") != "step":
            continue
        chart, step, reading = rec["chart"], rec["step"], rec.get("reading") or {}
        if "gsf_arcsec_per_ma" in reading:
            data.gsf = reading["gsf_arcsec_per_ma"]
        if "orientation" in reading and "-R" in chart:
            currents.setdefault(chart, {})[int(reading["orientation"])] = reading["currents_ma"]
        if step == "5.2" and chart in currents and len(currents[chart]) == 4:
            phase = "operating" if chart.startswith("4.3") else "shutdown"
            samples = [currents[chart][k] for k in (1, 2, 3, 4)]
            data.runs[phase].append(run_values(samples, data.gsf))
    return data, seed


def _served_without_truth(path: Path) -> bool:
    """The journal's run was against a served rack whose world was not the run's own."""
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            break
        if rec.get("kind") == "note" and rec.get("event") == "start":
            served = rec.get("served")
            return served is not None and not served.get("truth")
    return False


def analyse_journal(d: Path) -> dict:
    """`station gyrocompass-test --analyse DIR`: the phase analysis again, from the journal."""
    d = Path(d)
    data, seed = data_from_journal(d / "journal.jsonl")
    no_truth = _served_without_truth(d / "journal.jsonl")
    if not data.gsf:
        raise ValueError(f"{d / 'journal.jsonl'} holds no scale factor (section 4.1)")
    for ph in PHASES:
        if len(data.runs[ph]) < 2:
            raise ValueError(f"{d / 'journal.jsonl'} holds {len(data.runs[ph])} completed "
                             f"{ph} run(s): at least 2 are needed")
    runs, phases, tests, conclusions = analyse(data)
    truth = (CigtfRack(seed).world.truth_theta_arcsec()
             if seed is not None and not no_truth else None)
    res = {
        "seed": seed, "gsf": data.gsf, "runs": runs, "phases": phases,
        "delta_arcsec": conclusions["operating_instability_arcsec"],
        "Delta_arcsec": conclusions["shutdown_instability_arcsec"], "tests": tests,
        "truth": {"theta_arcsec": truth}, "from_journal": True,
    }
    (d / "gyrocompass_analysis.json").write_text(json.dumps(res, indent=1, sort_keys=True))
    return res


def render_tables(console, res: dict) -> None:
    """Run table, phase table and the section 5.4 tests, with rich."""
    from rich import box
    from rich.table import Table

    t = Table(title="Runs: theta and its standard error (arcsec)", box=box.SIMPLE_HEAD)
    for c in ("phase", "run", "theta", "sigma"):
        t.add_column(c, justify="right")
    for r in res["runs"]:
        t.add_row(r["phase"], str(r["run"]), f"{r['theta_arcsec']:+.2f}",
                  f"{r['sigma_arcsec']:.2f}")
    console.print(t)
    p = Table(title="Phases (eqs. 20-25)", box=box.SIMPLE_HEAD)
    for c in ("phase", "n", "theta", "sigma", "s", "instability"):
        p.add_column(c, justify="right")
    for ph in res["phases"]:
        p.add_row(ph["phase"], str(ph["n"]), f"{ph['theta_arcsec']:+.2f}",
                  f"{ph['sigma_arcsec']:.2f}", f"{ph['s_arcsec']:.2f}",
                  f"{ph['instability_arcsec']:.2f}")
    console.print(p)
    q = Table(title="Significance tests (section 5.4)", box=box.SIMPLE_HEAD)
    for c in ("test", "statistic", "threshold", "dof", "significant"):
        q.add_column(c, justify="left" if c == "test" else "right")
    for x in res["tests"]:
        q.add_row(x["name"], f"{x['statistic']:.3f}", f"{x['threshold']:.3f}",
                  str(x["dof"]), "yes" if x["significant"] else "no")
    console.print(q)


def run_gyrocompass_test(seed: int, out: Path, params: CigtfParams | None = None,
                         plan: TestPlan | None = None,
                         rack_hook: Callable[[CigtfRack], None] | None = None,
                         links: Path | None = None) -> dict:
    """Run the whole test into ``out``; ``rack_hook`` may inject faults into the rack.

    ``links``: run against the CIGTF rack served there instead (see the module doc);
    raises ``NoServedRack`` or ``WrongStation`` (both OSError/ValueError) if it is not.
    """
    out = Path(out)
    wall0 = time.perf_counter()
    st, rack, served = connect_rack(
        "cigtf", seed, params_digest("cigtf", params or CigtfParams()),
        lambda: CigtfRack(seed, params), open_cigtf_station, links, rack_hook)
    with journaled_run(out, st, rack, served, seed=seed, test="gyrocompass") as (
            run, extra, t_start):
        data = gyrocompass_test(st, run, plan)
        runs, phases, tests, conclusions = analyse(data)
        run.save_sheet("gyrocompass_runs", runs)
        run.save_sheet("gyrocompass_phases", phases)
        run.save_sheet("gyrocompass_conclusions", conclusions)
        write_sheets(out, run)
        res = {
            "seed": seed,
            "gsf": data.gsf,
            "runs": runs,
            "phases": phases,
            "delta_arcsec": conclusions["operating_instability_arcsec"],
            "Delta_arcsec": conclusions["shutdown_instability_arcsec"],
            "tests": tests,
            "truth": {"theta_arcsec": rack.world.truth_theta_arcsec()
                      if rack is not None else None},
            "sim_seconds": st.clock.now() - t_start,
            "wall_seconds": time.perf_counter() - wall0,
            **extra,
        }
        (out / "gyrocompass.json").write_text(json.dumps(res, indent=1, sort_keys=True))
        theta_plot(res, out / "gyrocompass.png")
        run.note(event="end", sim_seconds=st.clock.now() - t_start)
        return res
