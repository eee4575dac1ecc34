"""Fault injection from ``[faults.<instrument>]``: what the instruments do wrong, and what the
drivers and procedures report about it (docs/faults.md)."""

from __future__ import annotations

import contextlib
import json

import numpy as np
import pytest
from rich.console import Console

from laboratory.isu.day import DayRequest, run_day
from procedures.isu.alignment.sampling import collect, sample_outliers
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.turn_on import turn_on
from procedures.journal import Journal
from procedures.runner import ProcedureError, Run
from sim.timebase import ticks
from station.config.isu import ConfigError, load_config
from station.drivers.isu.ieu import PARTS
from station.errors import DriverError, LinkTimeout
from station.hil.realtime import RealtimeEnv
from station.racks.isu import SimulatedRack, open_isu_drivers

QUIET = Console(quiet=True)
IDN_COUNTER4 = b"ISU-LAB,FC-1,C4,1.0\n"


def faulty(faults: dict, seed: int | None = None):
    return load_config(seed=seed, overrides={"faults": faults})


@contextlib.contextmanager
def rig(faults: dict, seed: int | None = None):
    """A simulated rack with ``faults`` and the station bound to it."""
    cfg = faulty(faults, seed)
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    try:
        yield rack, st
    finally:
        st.close()
        rack.close()


def day(faults: dict, out, seed: int | None = None) -> dict:
    return run_day(DayRequest(faulty(faults, seed), out, only=("II-11",), quiet=True,
                              align=False), QUIET)


def journal(out) -> list[dict]:
    return [json.loads(x) for x in (out / "journal.jsonl").read_text().splitlines()]


# ----------------------------------------------------------------------------- no faults


def test_no_faults_arms_nothing():
    with rig({"table": {}, "ieu": {}}) as (rack, _):  # every field at its default
        assert all(i.reply_fault is None and not i.silent for i in rack.serial.values())
        assert rack.ieu.frame_fault is None and not rack.ieu.silent
        assert rack.serial["table"].stalled == set()


# ----------------------------------------------------------------------------- 1. latency


def test_latency_delays_each_reply_by_the_configured_time(cfg):
    base = cfg.instruments.serial.latency_s
    gap = cfg.instruments.ieu.frame_gap_s
    with rig({"counter2": {"latency_s": 0.75}, "ieu": {"latency_s": 0.2}}) as (_, st):
        clock = st.clock
        t0 = clock.now()
        assert st.counters[2].identify() == "ISU-LAB,FC-1,C2,1.0"
        assert clock.now() - t0 == pytest.approx(base + 0.75, abs=1e-9)
        t0 = clock.now()
        st.counters[1].identify()  # a neighbour without the fault
        assert clock.now() - t0 == pytest.approx(base, abs=1e-9)
        t0 = clock.now()
        assert st.ieu.status()["State"] == 0
        assert clock.now() - t0 == pytest.approx(gap + 0.2, abs=1e-9)
        # a reply held longer than the driver waits is a timeout naming the instrument
        with pytest.raises(LinkTimeout) as e:
            st.counters[2].query("*IDN?", timeout=0.5)
        assert e.value.instrument == "counter2"


def test_latency_delays_the_day_but_it_completes(tmp_path):
    clean = day({}, tmp_path / "clean")
    slow = day({"table": {"latency_s": 0.25}, "counter1": {"latency_s": 0.5}}, tmp_path / "slow")
    assert slow["sim_seconds"] > clean["sim_seconds"]
    step = {(r["chart"], r["step"]): r["t_sim"] for r in journal(tmp_path / "clean")
            if r["kind"] == "step"}
    slow_step = {(r["chart"], r["step"]): r["t_sim"] for r in journal(tmp_path / "slow")
                 if r["kind"] == "step"}
    assert slow_step.keys() == step.keys()  # every step of the day, none failed
    # Chart I-1 step 1 asks each instrument *IDN? once: 0.25 s + 0.5 s later
    assert slow_step[("I-1", "1")] - step[("I-1", "1")] == pytest.approx(0.75, abs=1e-9)


# ----------------------------------------------------------------------------- 2. corruption


def test_every_corrupted_reply_is_reported_naming_the_counter():
    with rig({"counter3": {"corrupt_rate": 0.1}}) as (rack, st):
        fault = rack.serial["counter3"].reply_fault
        outcomes = []
        for _ in range(60):
            before = fault.bytes_corrupted
            try:
                st.counters[3].standby()  # "OK\n": any flipped bit shows
                raised = None
            except DriverError as e:
                raised = e
            corrupted = fault.bytes_corrupted > before
            assert (raised is not None) == corrupted
            if raised is not None:
                assert raised.instrument == "counter3"
                assert str(raised).startswith("counter3 (sim://counter3")
            outcomes.append(corrupted)
        assert 0 < sum(outcomes) < len(outcomes)
        assert not rack.serial["counter3"].operating  # the counter itself obeyed every STBY


def test_corrupted_counter_stops_turn_on_naming_chart_step_and_counter(tmp_path):
    with rig({"counter3": {"corrupt_rate": 0.05}}) as (_, st):
        run = Run(st.clock, Journal(tmp_path / "j.jsonl"))
        with pytest.raises(ProcedureError) as e:
            turn_on(st, run, warmup_s=1.0)
    err = e.value
    assert (err.chart, err.step) == ("I-1", "4")  # the counters' self-test and standby
    cause = err.__cause__
    assert isinstance(cause, DriverError) and cause.instrument == "counter3"
    assert cause.step == "Chart I-1 step 4"
    assert str(err).startswith("Chart I-1, step 4 (")
    assert "counter3 (sim://counter3" in str(err) and "during Chart I-1 step 4" in str(err)


# ----------------------------------------------------------------------------- 3. lost bytes


def test_lost_reply_bytes_are_reported_naming_the_instrument():
    with rig({"patch_panel": {"drop_rate": 0.15}}) as (rack, st):
        fault = rack.serial["patch_panel"].reply_fault
        pp = st.patch_panel
        kinds = set()
        for _ in range(60):
            before = fault.bytes_dropped
            t0 = st.clock.now()
            try:
                pp.command("*CLS")
                raised = None
            except DriverError as e:
                raised = e
            assert (raised is not None) == (fault.bytes_dropped > before)
            if isinstance(raised, LinkTimeout):  # the newline was lost: no end of reply
                assert "no reply to '*CLS' within 5 s" in str(raised)
                assert st.clock.now() - t0 == pytest.approx(5.0, abs=1e-6)
                kinds.add("timeout")
            elif raised is not None:  # "OK" came short
                assert "unexpected reply" in str(raised)
                kinds.add("short")
            if raised is not None:
                assert raised.instrument == "patch_panel"
                assert str(raised).startswith("patch_panel (sim://patch_panel")
        assert kinds == {"timeout", "short"}


# ----------------------------------------------------------------------------- 4. silence


def test_silent_table_times_out_after_the_time_but_still_obeys():
    with rig({"table": {"silent_after_s": 100.0}}) as (rack, st):
        assert st.table.interlock() == "CLOSED"
        st.clock.sleep(99.0 - st.clock.now())
        assert st.table.query("PPR?") == "1"
        st.clock.sleep(101.0 - st.clock.now())
        t0 = st.clock.now()
        with pytest.raises(LinkTimeout) as e:
            st.table.set_pulses_per_rev(90)
        assert e.value.instrument == "table" and "no reply to 'PPR 90'" in str(e.value)
        assert st.clock.now() - t0 == pytest.approx(5.0, abs=1e-6)
        assert rack.world.table.pulses_per_rev == 90  # it listens: the command was obeyed


def test_silent_ieu_times_out_naming_the_ieu():
    with rig({"ieu": {"silent_after_s": 30.0}}) as (_, st):
        assert st.ieu.status()["State"] == 0
        st.clock.sleep(31.0)
        with pytest.raises(LinkTimeout) as e:
            st.ieu.status()
        assert e.value.instrument == "ieu" and "no frame within 5 s" in str(e.value)


def test_silent_bubble_levels_stop_the_day_at_the_next_reading(tmp_path):
    with pytest.raises(ProcedureError) as e:
        day({"bubble_levels": {"silent_after_s": 1000.0}}, tmp_path)
    err = e.value
    assert isinstance(err.__cause__, LinkTimeout)
    assert err.__cause__.instrument == "bubble_levels"
    assert f"during Chart {err.chart} step {err.step}" in str(err)
    assert "no reply to 'LEV?'" in str(err)
    recs = journal(tmp_path)
    # turn-on read the levels before they fell silent; the failing step is after 1000 s
    assert ("I-1", "9") in {(r["chart"], r["step"]) for r in recs if r["kind"] == "step"}
    assert recs[-1]["kind"] == "failed" and recs[-1]["step"] == err.step
    assert recs[-1]["t_sim"] > 1000.0


# ----------------------------------------------------------------------------- 5, 6. the IEU

SAMPLING = (1000, 4, 10)  # period (S2^T pulses: 0.1 s), samples per interval, K


def collect_with(faults: dict, seed: int | None = None):
    """IEU data collected by the alignment's sampling, and the frames the IEU put on the bus."""
    with rig(faults, seed) as (rack, st):
        frames: list = []
        rack.ieu.listeners.append(lambda t, i, d: frames.append((t, i, bytes(d))))
        try:
            rec = collect(st, *SAMPLING)
        except Exception as e:  # noqa: BLE001 - the test looks at what was raised
            rec = e
        return rec, frames, rack.ieu.frame_fault


def same_data(a, b) -> bool:
    return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("gyro", "strings", "timer"))


def test_lost_ieu_frames_are_recovered_to_the_clean_data():
    clean, _, _ = collect_with({})
    rec, _, fault = collect_with({"ieu": {"drop_rate": 0.05}})
    assert fault.frames_dropped > 0
    assert rec.recoveries and rec.garbled == 0
    assert len(rec.recoveries) <= fault.frames_dropped  # each recovery follows a loss
    assert all(set(r["missing"]) <= set(PARTS) for r in rec.recoveries)
    assert same_data(rec, clean) and (rec.first_seq, rec.last_seq) == (
        clean.first_seq, clean.last_seq)
    assert rec.summary()["recovered_samples"] == rec.recoveries


def test_ieu_losses_beyond_recovery_are_an_error_naming_the_ieu():
    rec, _, fault = collect_with({"ieu": {"drop_rate": 0.3}}, seed=0)
    assert isinstance(rec, DriverError) and rec.instrument == "ieu"
    assert "still incomplete after 3 resends" in str(rec)
    assert fault.frames_dropped > 0


def test_altered_ieu_frames_differ_from_the_clean_ones_in_one_byte():
    """On the bus: the same frames at the same times, each altered one off by one byte."""
    def sample_for(faults):
        with rig(faults) as (rack, st):
            frames: list = []
            rack.ieu.listeners.append(lambda t, i, d: frames.append((t, i, bytes(d))))
            st.ieu.start(1000)
            st.clock.sleep(20.0)
            rack.ieu.listeners.clear()
            return frames, rack.ieu.frame_fault

    clean, _ = sample_for({})
    bad, fault = sample_for({"ieu": {"corrupt_rate": 0.1}})
    again, _ = sample_for({"ieu": {"corrupt_rate": 0.1}})
    assert again == bad  # same seed, same alterations
    assert [(t, i, len(d)) for t, i, d in bad] == [(t, i, len(d)) for t, i, d in clean]
    altered = [(a, b) for (_, _, a), (_, _, b) in zip(clean, bad, strict=True) if a != b]
    assert len(altered) == fault.frames_corrupted > 0
    for a, b in altered:
        assert sum(x != y for x, y in zip(a, b, strict=True)) == 1


@pytest.mark.parametrize("seed", [0, 1, 17])
def test_altered_ieu_frames_fail_the_sample_check_and_are_sent_again(seed):
    """Every sample closes with a CRC-32C of its count frames (IEU_CHECK): an altered count,
    sequence number, timer or flag fails it, the sample is asked for again and the data
    equal a clean run's. (Without the check, seed 17 altered a pulse count unnoticed and
    seeds 0 and 1 stopped on a misleading RESEND refusal or timer count.)"""
    clean, _, _ = collect_with({}, seed=seed)
    rec, _, fault = collect_with({"ieu": {"corrupt_rate": 0.02}}, seed=seed)
    assert fault.frames_corrupted >= 1
    assert not isinstance(rec, Exception), rec
    assert same_data(rec, clean) and (rec.first_seq, rec.last_seq) == (
        clean.first_seq, clean.last_seq)
    assert any(r["failed_check"] for r in rec.recoveries)
    assert len(rec.recoveries) <= 2 * fault.frames_corrupted  # each follows an alteration


def test_a_count_altered_past_the_check_is_found_among_its_neighbours():
    """Defence in depth behind the IEU's CRC: a count altered after the check (in the host,
    say) lies beyond K_READING sigma of its neighbours' running median and is listed with
    its sample and signal; untouched counts are not (collect_checked refuses such a record)."""
    noise = NoiseSpec()
    rng = np.random.default_rng(5)
    n = 120
    rates = np.array([400, -250, 90, 20000, 20500, 19800, 20100, 20050, 19950])
    counts = (np.floor(np.cumsum(np.tile(rates + rng.uniform(0, 0.3, 9), (n, 1)), axis=0)
                       + rng.uniform(0, 1, 9)).astype(np.int64))
    counts = np.diff(np.vstack([np.zeros((1, 9), np.int64), counts]), axis=0)[1:]
    seqs = np.arange(len(counts)) + 1000
    assert sample_outliers(counts, seqs, noise) == []
    counts[57, 4] += 256  # one byte of a count changed
    (o,) = sample_outliers(counts, seqs, noise)
    assert (o["seq"], o["signal"]) == (1057, "A1S2") and o["deviation_sigma"] > 6.0


# ----------------------------------------------------------------------------- 7. stall


def test_stalled_axis_stays_put_and_the_wait_names_it():
    with rig({"table": {"stall_axis": 2, "stall_after_s": 1.0}}) as (_, st):
        tb = st.table
        tb.move(2, 90.0)  # 9 s of slew: the drive seizes 1 s into it
        tb.move(3, 30.0)
        with pytest.raises(LinkTimeout) as e:
            tb.wait_still(timeout=20.0)
        msg = str(e.value)
        assert e.value.instrument == "table"
        assert "axis 2 (MOVING) not settled after 20 s" in msg and "axis 3" not in msg
        stuck = tb.position(2)
        assert 1.0 < stuck < 20.0  # stopped short, about where it was at 1 s
        assert tb.position(3) == pytest.approx(30.0, abs=1e-3)  # the other axes still work
        tb.move(2, 180.0)
        st.clock.sleep(30.0)
        assert tb.position(2) == stuck and tb.status()[1] == "MOVING"
        tb.rotate(2, 10.0)
        assert tb.status()[1] == "ACCEL" and tb.rate(2) == 0.0
        tb.stop(2)  # nothing left to do: the controller reports the axis at rest
        assert tb.status() == ["HOLD"] * 4
        tb.move(2, stuck)  # already there: in position
        assert tb.status()[1] == "HOLD"


def test_stalled_axis_stops_the_day_at_the_first_position_setting(tmp_path):
    with pytest.raises(ProcedureError) as e:
        day({"table": {"stall_axis": 2}}, tmp_path)
    err = e.value
    cause = err.__cause__
    assert isinstance(cause, LinkTimeout) and cause.instrument == "table"
    assert "axis 2 (MOVING) not settled" in str(err)
    assert f"Chart {err.chart}, step {err.step}" in str(err)
    assert (err.chart, err.step) == ("I-2", "2")  # set position 0: the first real move
    assert journal(tmp_path)[-1]["kind"] == "failed"


# ----------------------------------------------------------------------------- 8. determinism


def idn_replies(cfg, n: int, env=None) -> tuple[bytes, object]:
    """Counter 4's reply bytes to ``n`` *IDN? queries, straight off the instrument."""
    rack = SimulatedRack(cfg, env=env)
    try:
        inst = rack.serial["counter4"]
        for _ in range(n):
            inst.receive(b"*IDN?\n")
            rack.env.run(until=rack.env.now + ticks(0.01))
        return bytes(inst.output), inst.reply_fault
    finally:
        rack.close()


def test_same_seed_same_corruption_byte_for_byte():
    n, rate = 200, 0.05
    faults = {"counter4": {"corrupt_rate": rate}}
    a, fault = idn_replies(faulty(faults, seed=11), n)
    b, _ = idn_replies(faulty(faults, seed=11), n)
    served, _ = idn_replies(faulty(faults, seed=11), n, env=RealtimeEnv())
    other, _ = idn_replies(faulty(faults, seed=12), n)
    clean = IDN_COUNTER4 * n
    assert a == b == served  # virtual or served rack: the same bytes
    assert other != a
    assert len(a) == len(clean)
    flips = [bin(x ^ y).count("1") for x, y in zip(a, clean, strict=True) if x != y]
    assert set(flips) == {1}  # one bit per corrupted byte
    assert len(flips) == fault.bytes_corrupted and fault.bytes_seen == len(clean)
    expected, sd = rate * len(clean), (rate * (1 - rate) * len(clean)) ** 0.5
    assert abs(len(flips) - expected) < 4 * sd


# ----------------------------------------------------------------------------- 9. config


@pytest.mark.parametrize(
    ("faults", "where"),
    [
        ({"counter9": {"latency_s": 1.0}}, "faults.counter9"),
        ({"table": {"latency_s": -0.1}}, "faults.table.latency_s"),
        ({"counter1": {"drop_rate": 1.0}}, "faults.counter1.drop_rate"),
        ({"ieu": {"corrupt_rate": 1.5}}, "faults.ieu.corrupt_rate"),
        ({"oscillator": {"silent_after_s": -1.0}}, "faults.oscillator.silent_after_s"),
        ({"counter2": {"stall_axis": 2}}, "faults.counter2.stall_axis"),
        ({"ieu": {"stall_after_s": 5.0}}, "faults.ieu.stall_after_s"),
        ({"table": {"stall_axis": 5}}, "faults.table.stall_axis"),
        ({"table": {"stall_after_s": 5.0}}, "faults.table.stall_after_s"),
        ({"table": {"jam": True}}, "faults.table.jam"),
    ],
)
def test_bad_fault_config_names_the_field(faults, where):
    with pytest.raises(ConfigError) as e:
        faulty(faults)
    assert where in str(e.value)
