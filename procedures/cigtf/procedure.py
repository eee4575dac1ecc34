"""The CIGTF standard gyrocompassing accuracy test (report 001, section 4) as check-sheets.

Steps are numbered by the report's sections; the words are ours. Every run is its own
check-sheet (chart 4.3-Rnn for the operating phase, 4.4-Rnn for the shutdown phase) whose
steps carry the ten averaged currents of each orientation and, last, the run's theta.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from functools import partial

from procedures.cigtf.analysis import OrientationValues, RunValues, run_values
from procedures.cigtf.scale import gsf_from_turn
from procedures.cigtf.setup import pretest_setup
from procedures.runner import CheckSheetRun, Run
from station.drivers.cigtf import CigtfDrivers
from station.errors import CheckFailed


@dataclass(frozen=True)
class TestPlan:
    samples: int = 10  # ten-second averages per orientation
    settle_s: float = 120.0  # after the fixture holds, before the first average
    operating_runs: int = 25
    shutdown_runs: int = 10
    initial_warmup_s: float = 7200.0
    shutdown_s: float = 7200.0
    warmup_s: float = 7200.0
    move_timeout_s: float = 120.0
    pretest_setup: bool = True  # section 4.1's set-up first (procedures.cigtf.setup)
    # orientation 1's vertical null, whole degrees: the input axis that far from west
    # (section 1's input-axis azimuth variation; 0 in the standard test)
    azimuth_deg: int = 0
    # the spin motor's supply, volts, set through the power supply before turn-on
    # (section 1's parameter variation); None: left as the supply is (the nominal 26 V)
    rotor_voltage_v: float | None = None


@dataclass
class TestData:
    gsf: float = 0.0
    setup: dict | None = None  # what the pre-test set-up left (b, c, a + d), arcsec
    rotor_voltage_v: float | None = None  # the supply as step 4.0.0 set it (None: not set)
    runs: dict[str, list[RunValues]] = field(
        default_factory=lambda: {"operating": [], "shutdown": []})


# (section, words, axis, turn) of 4.2.2-4.2.4; orientation 1 is reached by 4.2.1
TURNS = (
    ("4.2.2", "turn 180 deg about the vertical axis: orientation 2 (O up, I east)", "V", 180),
    ("4.2.3", "turn 180 deg about the horizontal axis: orientation 3 (O down, I west)", "H",
     180),
    ("4.2.4", "turn 180 deg about the vertical axis: orientation 4 (O down, I east)", "V", 180),
)


def _settle_and_average(st: CigtfDrivers, plan: TestPlan) -> list[float]:
    st.fixture.wait_hold(plan.move_timeout_s)
    st.clock.sleep(plan.settle_s)
    return [st.dvm.average() for _ in range(plan.samples)]


def scale_factor(st: CigtfDrivers, run: Run, plan: TestPlan) -> float:
    """Section 4.1: orientation 1, ten averages, a +1 deg turn, ten averages, GSF (eq. 14)."""
    with run.sheet("4.1", "Gyrocompassing scale factor") as sh:
        with sh.step("4.1.1", "fixture to orientation 1 (O up, I west); settle; ten "
                     "10-s averages of torquer current") as s:
            st.fixture.move("V", plan.azimuth_deg % 360)
            st.fixture.wait_hold(plan.move_timeout_s)
            st.fixture.move("H", 0)
            i1 = _settle_and_average(st, plan)
            s.reading = {"currents_ma": i1}
        with sh.step("4.1.2", "turn +1 deg about the vertical axis; settle; ten averages") as s:
            st.fixture.turn("V", 1)
            i1t = _settle_and_average(st, plan)
            s.reading = {"currents_ma": i1t}
        with sh.step("4.1.3", "GSF = 900 / (I1 - I1') arcsec/mA; back to orientation 1") as s:
            gsf = gsf_from_turn(sum(i1) / len(i1), sum(i1t) / len(i1t))
            st.fixture.turn("V", -1)
            st.fixture.wait_hold(plan.move_timeout_s)
            s.reading = {"gsf_arcsec_per_ma": gsf}
    return gsf


def north_determination(st: CigtfDrivers, run: Run, plan: TestPlan, chart: str, title: str,
                        gsf: float,
                        preamble: Callable[[CheckSheetRun], None] | None = None) -> RunValues:
    """Section 4.2: one run (four orientations), journaled step by step; eqs. 18-19."""
    samples: list[list[float]] = []
    with run.sheet(chart, title) as sh:
        if preamble is not None:
            preamble(sh)
        with sh.step("4.2.1", "fixture to orientation 1 (O up, I west); settle; ten "
                     "10-s averages") as s:
            st.fixture.move("V", plan.azimuth_deg % 360)
            st.fixture.wait_hold(plan.move_timeout_s)
            st.fixture.move("H", 0)
            samples.append(_settle_and_average(st, plan))
            s.reading = {"orientation": 1, "currents_ma": samples[-1]}
        for k, (num, text, axis, deg) in enumerate(TURNS, start=2):
            with sh.step(num, f"{text}; settle; ten 10-s averages") as s:
                st.fixture.turn(axis, deg)
                samples.append(_settle_and_average(st, plan))
                s.reading = {"orientation": k, "currents_ma": samples[-1]}
        with sh.step("5.2", "run theta = GSF (I1 + I3 - I2 - I4) and its sigma "
                     "(eqs. 15-19)") as s:
            rv = run_values(samples, gsf)
            s.reading = {"theta_arcsec": rv.theta, "sigma_arcsec": rv.sigma}
    return rv


def warm_up(st: CigtfDrivers, run: Run, plan: TestPlan) -> None:
    """Section 4.0: gyro power on in torque-to-balance and the initial warm-up."""
    with run.sheet("4.0", "Gyro turn-on and warm-up") as sh:
        if plan.rotor_voltage_v is not None:
            v = plan.rotor_voltage_v
            with sh.step("4.0.0", f"set the rotor supply to {v:g} V (gyro off)") as s:
                st.power.off()
                st.power.set_rotor_voltage(v)
                got = st.power.rotor_voltage()
                if abs(got - v) > 0.005:
                    raise CheckFailed(f"rotor supply reads {got:g} V, set to {v:g} V")
                s.reading = {"rotor_voltage_v": got}
        with sh.step("4.0.1", "gyro power on in torque-to-balance") as s:
            st.power.on()
            s.reading = {"power": "ON"}
        with sh.step("4.0.2", "warm up") as s:
            st.clock.sleep(plan.initial_warmup_s)
            on, since = st.power.status()
            if not on:
                raise CheckFailed("gyro power is off after the warm-up")
            s.reading = {"on_s": since}


def _as_record(rv: RunValues) -> dict:
    """A run's values in their journal form (a block's result)."""
    return asdict(rv)


def _run_record(st: CigtfDrivers, run: Run, plan: TestPlan, chart: str, title: str,
                gsf: float,
                preamble: Callable[[CheckSheetRun], None] | None = None) -> dict:
    """One run of section 4.2 as a block's result."""
    return _as_record(north_determination(st, run, plan, chart, title, gsf, preamble))


def _from_record(d: dict) -> RunValues:
    return RunValues(d["theta"], d["sigma"],
                     tuple(OrientationValues(**o) for o in d["orientations"]))


def gyrocompass_test(st: CigtfDrivers, run: Run, plan: TestPlan | None = None) -> TestData:
    """The pre-test set-up (4.1-S, with ``plan.pretest_setup``), turn-on and warm-up, 4.1,
    the operating phase (4.3) and the shutdown phase (4.4).

    Each of them, and each run, is a journaled block (``Run.block``): a resume over links
    restores the completed ones and repeats only the interrupted run (the warm-up too,
    block "4.0", when the served rack was restarted)."""
    plan = plan or TestPlan()
    data = TestData()
    if plan.pretest_setup:
        data.setup = run.block("4.1-S", lambda: pretest_setup(st, run), dict)
    run.block("4.0", lambda: warm_up(st, run, plan), lambda _: None)
    data.rotor_voltage_v = plan.rotor_voltage_v
    data.gsf = run.block("4.1", lambda: scale_factor(st, run, plan), float)
    for i in range(1, plan.operating_runs + 1):
        chart = f"4.3-R{i:02d}"
        rv = run.block(chart, partial(_run_record, st, run, plan, chart,
                                      f"Operating phase, run {i}", data.gsf), _from_record)
        data.runs["operating"].append(rv)

    def shutdown(sh: CheckSheetRun) -> None:
        with sh.step("4.4.1", "gyro shutdown") as s:
            st.power.off()
            st.clock.sleep(plan.shutdown_s)
            s.reading = {"off_s": plan.shutdown_s}
        with sh.step("4.4.2", "gyro power on; warm up") as s:
            st.power.on()
            st.clock.sleep(plan.warmup_s)
            s.reading = {"on_s": st.power.status()[1]}
    for i in range(1, plan.shutdown_runs + 1):
        chart = f"4.4-R{i:02d}"
        rv = run.block(chart, partial(_run_record, st, run, plan, chart,
                                      f"Shutdown phase, run {i}", data.gsf, shutdown),
                       _from_record)
        data.runs["shutdown"].append(rv)
    return data
