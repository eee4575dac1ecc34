"""`station gyrocompass-test`: the CIGTF gyrocompassing accuracy test (report 001) in
virtual time, its journal, sheets (run table, phase table, conclusions), gyrocompass.json
and a plot of theta per run.

With ``links`` (``--links DIR``) the same procedure and drivers run against a rack served
by ``station serve --station cigtf --links DIR``, over its ptys and on a WallClock on the
rack's time. The truth (eq. 26) comes from a rack built here with the run's seed and
params and never run; it is left out (None) unless the served session has that seed and
config digest."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING

from laboratory import registry
from laboratory.cigtf.plot_child import PLOTS
from laboratory.cigtf.plots import theta_plot  # noqa: F401 - re-exported
from laboratory.connect import connect, journaled_run
from laboratory.export import write_results_csv
from laboratory.identity import Identifying
from laboratory.plot_worker import PlotWorker
from laboratory.record import write_json, write_sheets
from laboratory.rundir import JOURNAL, RunDirError, prepare
from laboratory.seeded import Seeded
from laboratory.shown import Shown
from laboratory.verdicts import judge_phases, run_verdict, truth_check
from procedures.cigtf.analysis import phase_values, run_values
from procedures.cigtf.budget import Eq27Values, budget_rows, corrected_phases
from procedures.cigtf.procedure import TestData, TestPlan, gyrocompass_test
from procedures.cigtf.significance import TestOutcome, judge_phase, shutdown_f_test
from procedures.journal import JournalError, scan
from sim.cigtf.world import CigtfParams, CigtfWorld
from sim.units import to_arcsec
from station.config.cigtf import CigtfConfig, Eq27Config
from station.config.limits import CigtfLimits
from station.hil.session import params_digest
from station.racks.cigtf import CigtfRack

if TYPE_CHECKING:
    from rich.console import Console

PHASES = ("operating", "shutdown")
# a restarted served rack powered the gyro off and stands as installed: its set-up and
# warm-up again
RENEW = ("4.1-S", "4.0")


def _test(name: str, t: TestOutcome) -> dict:
    return {"name": name, "statistic": t.statistic, "threshold": t.threshold,
            "dof": list(t.dof), "significant": t.significant}


TEST_NAMES = {
    "operating": ("5.4.2 operating F (delta^2 / s1^2)", "5.4.1 operating t |theta1 / se|"),
    "shutdown": ("5.4.3 shutdown F (Delta^2 / s2^2)", "5.4.1 shutdown t |theta2 / se|"),
}


def analyse(data: TestData) -> tuple[list[dict], list[dict], list[dict], dict]:
    """Section 5: run table, phase table, significance tests and conclusions of a test.

    A phase with fewer than two completed runs (a test stopped early) has no phase values
    and no tests; the shutdown-versus-operating test needs both phases."""
    runs = [{"phase": ph, "run": i, "theta_arcsec": r.theta, "sigma_arcsec": r.sigma}
            for ph in PHASES for i, r in enumerate(data.runs[ph], start=1)]
    pv = {ph: phase_values(data.runs[ph]) for ph in PHASES if len(data.runs[ph]) >= 2}
    phases = [{"phase": ph, "theta_arcsec": p.theta, "sigma_arcsec": p.sigma,
               "s_arcsec": p.s, "n": p.n, "instability_arcsec": p.instability}
              for ph, p in pv.items()]
    verdicts = {ph: judge_phase(p) for ph, p in pv.items()}
    tests = []
    for ph, v in verdicts.items():
        tests += [_test(TEST_NAMES[ph][0], v.noise_test), _test(TEST_NAMES[ph][1], v.mean_test)]
    conclusions: dict = {"gsf_arcsec_per_ma": data.gsf}
    for ph, v in verdicts.items():
        conclusions[ph] = {"theta_arcsec": v.phase.theta,
                           "standard_error_arcsec": v.standard_error,
                           "bias_significant": v.mean_test.significant,
                           "instability_exceeds_noise": v.noise_test.significant}
        conclusions[f"{ph}_instability_arcsec"] = v.phase.instability
    if len(pv) == 2:
        both = shutdown_f_test(pv["operating"], pv["shutdown"])
        tests.append(_test("5.4.4 shutdown vs operating F (Delta^2 / delta^2)", both))
        conclusions["shutdown_adds_instability"] = both.significant
    return runs, phases, tests, conclusions


def eq27_values(cfg: Eq27Config | None, latitude_deg: float) -> Eq27Values | None:
    """The laboratory's values for eq. 27 when the correction is asked for, else None."""
    if cfg is None or not cfg.apply:
        return None
    return Eq27Values(latitude_deg, **cfg.model_dump(exclude={"apply"}))


def budget_record(truth: dict[str, float] | None, lab: Eq27Values | None,
                  phases: list[dict]) -> tuple[list[dict], dict | None]:
    """The eq. 26-27 budget table and, with eq. 27, each phase's corrected theta judged
    against -(a + d), the truth of an exact correction (``truth['north']``)."""
    rows = budget_rows(truth, lab)
    if lab is None:
        return rows, None
    north = None if truth is None else truth["north"]
    fixed = corrected_phases(phases, lab)
    for p in fixed:
        p["truth"] = north
        p["truth_check"] = truth_check([None if north is None else p["theta_arcsec"] - north],
                                       [p["sigma_arcsec"]])
    corr, sigma = lab.correction()
    return rows, {"applied": True, "correction_arcsec": corr, "sigma_arcsec": sigma,
                  "values": asdict(lab), "phases": fixed}


def set_up_twin(twin: CigtfRack) -> None:
    """Level and align a twin rack as the run's own set-up did (the same seed, plan and
    virtual time give the same adjustments): its truth is then the run's."""
    import tempfile

    from procedures.cigtf.setup import pretest_setup
    from procedures.journal import Journal
    from procedures.runner import Run
    from station.racks.cigtf import open_cigtf_drivers

    st = open_cigtf_drivers(twin)
    with tempfile.TemporaryDirectory() as d:
        pretest_setup(st, Run(st.clock, Journal(Path(d) / JOURNAL)))


def setup_record(setup: dict | None, world: CigtfWorld | None) -> list[dict] | None:
    """What the pre-test set-up left (b, c from the levels, a + d from the autocollimator),
    each with its sigma and the simulator's truth after the set-up (None over links)."""
    if setup is None:
        return None
    m = None if world is None else world.misalignments
    truths = {"b": None if m is None else to_arcsec(m.b),
              "c": None if m is None else to_arcsec(m.c),
              "a + d": None if m is None else to_arcsec(m.a + m.d)}
    rows = []
    for name, key in (("b", "b"), ("c", "c"), ("a + d", "north")):
        est, sd, truth = setup[f"{key}_arcsec"], setup[f"{key}_sigma_arcsec"], truths[name]
        rows.append({"instrument": "set-up", "parameter": name, "units": "arcsec",
                     "estimate": est, "sigma": sd,
                     "truth": truth, "truth_check": truth_check(
                         [None if truth is None else est - truth], [sd])})
    return rows


def data_from_records(records: list[dict]) -> tuple[TestData, dict | None]:
    """The test data of a journal's records: every completed run (its step 5.2 recorded
    after its four orientations); and the run's start note."""
    data = TestData()
    start = None
    currents: dict[str, dict[int, list[float]]] = {}
    for rec in records:
        if start is None and rec["kind"] == "note" and rec["event"] == "start":
            start = rec
        if rec["kind"] != "step":
            continue
        chart, step, reading = rec["chart"], rec["step"], rec.get("reading")
        reading = reading if isinstance(reading, dict) else {}
        if "gsf_arcsec_per_ma" in reading:
            data.gsf = float(reading["gsf_arcsec_per_ma"])
        if step == "4.0.0" and "rotor_voltage_v" in reading:  # the supply set by command
            data.rotor_voltage_v = float(reading["rotor_voltage_v"])
        if "orientation" in reading and "-R" in chart:
            if step == "4.2.1":  # a run (re)started: earlier partial orientations are void
                currents[chart] = {}
            currents.setdefault(chart, {})[int(reading["orientation"])] = reading["currents_ma"]
        if step == "5.2" and len(currents.get(chart, {})) == 4:
            phase = "operating" if chart.startswith("4.3") else "shutdown"
            samples = [currents[chart][k] for k in (1, 2, 3, 4)]
            data.runs[phase].append(run_values(samples, data.gsf))
    return data, start


def data_from_journal(path: Path) -> tuple[TestData, int | None]:
    """Rebuild the test data from a journal (checked; a torn last line is left out)."""
    data, start = data_from_records(scan(Path(path)).records)
    return data, None if start is None else start.get("seed")


def run_config(d: Path, config: Path | None) -> Path | None:
    """The configuration a re-analysis of the run in ``d`` uses: ``config`` when given,
    else the run's own saved DIR/config.toml (its truth needs the run's [cigtf] section),
    else None (the defaults: a record from before saved configurations)."""
    if config is not None:
        return config
    saved = Path(d) / "config.toml"
    return saved if saved.is_file() else None


def analyse_journal(d: Path, params: CigtfParams | None = None,
                    limits: CigtfLimits | None = None, eq27: Eq27Config | None = None) -> dict:
    """`station gyrocompass-test --analyse DIR`: the analysis of every run the journal
    completed, however the test ended; written to DIR/gyrocompass_analysis.json.

    The truth (eq. 26) is given when the journal's start note names the ``params``
    (default: the default fixture) by digest, and its run was virtual or served with truth.
    ``eq27``: the correction's values (default: those the run's start note recorded).
    """
    d = Path(d)
    if not d.is_dir():
        raise RunDirError(f"--analyse {d}: no such directory")
    path = d / JOURNAL
    try:
        records = scan(path).records
        data, start = data_from_records(records)
    except (KeyError, TypeError, ValueError) as e:  # a step reading that is not the test's
        raise JournalError(f"{path}: a step reading is not this test's: {e!r}") from None
    params = params or CigtfParams()
    seed = None if start is None else start.get("seed")
    served = (start or {}).get("served")
    truthful = (isinstance(seed, int) and (start or {}).get("params_digest")
                == params_digest("cigtf", params)
                and (served is None or bool(served.get("truth"))))
    runs, phases, tests, conclusions = analyse(data)
    truth = budget = None
    if truthful and isinstance(seed, int):
        if data.rotor_voltage_v is not None:  # the run set its supply (step 4.0.0)
            params = replace(params, rotor_voltage_v=data.rotor_voltage_v)
        twin = CigtfRack(seed, params)
        with twin:
            if params.pretest_setup:
                set_up_twin(twin)
            truth = twin.world.truth_theta_arcsec()
            budget = twin.world.truth_budget()
    judge_phases(phases, truth, limits or CigtfLimits())  # as the run judges them
    noted = (start or {}).get("eq27")
    if eq27 is None and isinstance(noted, dict):
        eq27 = Eq27Config(apply=True, **noted)
    budget_rows_, corrected = budget_record(budget, eq27_values(eq27, params.latitude_deg),
                                            phases)
    missing = [f"{ph}: {len(data.runs[ph])} completed run(s), a phase needs 2"
               for ph in PHASES if len(data.runs[ph]) < 2]
    res = {
        "seed": seed, "gsf": data.gsf or None, "runs": runs, "phases": phases,
        "delta_arcsec": conclusions.get("operating_instability_arcsec"),
        "Delta_arcsec": conclusions.get("shutdown_instability_arcsec"), "tests": tests,
        "truth": {"theta_arcsec": truth,
                  "north_arcsec": None if budget is None else budget["north"]},
        "budget": budget_rows_, "eq27": corrected,
        "from_journal": True, "complete": any(r["kind"] == "note" and r["event"] == "end"
                                              for r in records),
        "incomplete_phases": missing, "verdict": run_verdict(phases),
    }
    write_json(d / "gyrocompass_analysis.json", res)
    return res


def render_tables(console: Console, res: dict) -> None:
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
    b = Table(title="Error budget of theta (eqs. 26-27), arcsec", box=box.SIMPLE_HEAD)
    for c in ("term", "laboratory (eq. 27)", "sigma", "truth"):
        b.add_column(c, justify="left" if c == "term" else "right")

    def num(x: float | None, f: str) -> str:
        return "-" if x is None else format(x, f)
    for r in res.get("budget") or []:
        b.add_row(r["term"], num(r["lab_arcsec"], "+.3f"), num(r["lab_sigma_arcsec"], ".3f"),
                  num(r["truth"], "+.3f"))
    console.print(b)
    for r in res.get("setup") or []:
        console.print(f"set-up left {r['parameter']:>5}: {r['estimate']:+.2f} +/- "
                      f"{r['sigma']:.2f} arcsec (truth {num(r['truth'], '+.2f')})")
    for p in (res.get("eq27") or {}).get("phases", []):
        console.print(f"{p['phase']:>9}: theta (eq. 27) {p['theta_arcsec']:+.2f} +/- "
                      f"{p['sigma_arcsec']:.2f} arcsec (correction "
                      f"{p['correction_arcsec']:+.2f})")


def run_gyrocompass_test(seed: int, out: Path, params: CigtfParams | None = None,
                         plan: TestPlan | None = None,
                         rack_hook: Callable[[CigtfRack], None] | None = None,
                         links: Path | None = None, resume: bool = False,
                         limits: CigtfLimits | None = None,
                         eq27: Eq27Config | None = None,
                         show: Shown | None = None) -> dict:
    """Run the whole test into ``out``; ``rack_hook`` may inject faults into the rack;
    ``limits``: the acceptance limits of delta and Delta (default: station/config/limits.py).

    ``links``: run against the CIGTF rack served there instead (see the module doc);
    raises ``NoServedRack`` or ``WrongStation`` (both OSError/ValueError) if it is not.
    ``resume``: continue the interrupted test in ``out`` (replayed and checked against its
    journal in virtual time); ``out`` must hold no record otherwise (RunDirError).
    ``eq27``: the eq. 27 correction's values; applied (and recorded in the start note, for
    ``--analyse``) when ``eq27.apply``. The budget table is written in any case.
    ``show``: the command's display of the results, called with them while the plot is
    drawn (issue 17).
    """
    out = Path(out)
    params = params or CigtfParams()
    plan = plan or TestPlan(pretest_setup=params.pretest_setup)
    prepare(out, resume, links)
    wall0 = time.perf_counter()
    digest = params_digest("cigtf", params)
    lab27 = eq27_values(eq27, params.latitude_deg)
    extra_start = {} if eq27 is None or not eq27.apply else {
        "eq27": eq27.model_dump(exclude={"apply"})}
    conn = connect(registry.get("cigtf"), Seeded(params, seed), links, rack_hook)
    st, world = conn.drivers, conn.coefficient_world
    with PlotWorker(PLOTS) as plots, journaled_run(  # plots: matplotlib imported meanwhile
            out, conn, resume, renew=RENEW, seed=seed, test="gyrocompass", params_digest=digest,
            **extra_start,
            identify=Identifying("cigtf", "gyrocompass-test", seed, "cigtf", CigtfConfig,
                                 params)) as (run, extra, t_start):
        data = gyrocompass_test(st, run, plan)
        runs, phases, tests, conclusions = analyse(data)
        truth = world.truth_theta_arcsec() if world is not None else None
        budget = world.truth_budget() if world is not None else None
        judge_phases(phases, truth, limits or CigtfLimits())
        plots.draw([(f"{PLOTS}:theta_plot", {  # drawn while the record is written
            "res": {"runs": runs, "phases": phases, "truth": {"theta_arcsec": truth}},
            "path": out / "gyrocompass.png"})])
        budget_table, corrected = budget_record(budget, lab27, phases)
        setup = setup_record(data.setup, world)
        if setup is not None:
            run.save_sheet("gyrocompass_setup", setup)
        run.save_sheet("gyrocompass_runs", runs)
        run.save_sheet("gyrocompass_phases", phases)
        run.save_sheet("gyrocompass_conclusions", conclusions)
        run.save_sheet("gyrocompass_budget", budget_table)
        write_sheets(out, run)
        res = {
            "seed": seed,
            "gsf": data.gsf,
            "runs": runs,
            "phases": phases,
            "delta_arcsec": conclusions.get("operating_instability_arcsec"),
            "Delta_arcsec": conclusions.get("shutdown_instability_arcsec"),
            "tests": tests,
            "truth": {"theta_arcsec": truth,
                      "north_arcsec": None if budget is None else budget["north"]},
            "budget": budget_table,
            "setup": setup,
            "eq27": corrected,
            "verdict": run_verdict(phases),
            "sim_seconds": st.clock.now() - t_start,
            "wall_seconds": time.perf_counter() - wall0,
            **extra,
        }
        write_json(out / "gyrocompass.json", res)
        write_results_csv(out, res["runs"], "gyrocompass.csv")
        plots.wait(meanwhile=lambda: (show or Shown(None)).meanwhile(res))
        run.note(event="end", sim_seconds=st.clock.now() - t_start)
        return res
