"""Every serial instrument answers as a SCPI device would (issue 13): each command word takes
exactly the arguments its synopsis allows, in the strict grammars of docs/protocols.md;
``*CLS`` empties the output and error queues; the output queue is bounded; settings the
physical instrument cannot sustain are refused; a fault of the simulation is ERR 200.

The property tests judge lines against tests/instrument_grammar.py, an oracle written from
the documentation (the fuzzer bench/fuzz_instruments.py uses the same oracle at 10^5 lines).
"""

from __future__ import annotations

import random
import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from instrument_grammar import GRAMMARS, Grammar

from instruments.base import MAX_REPLIES, ByteInstrument, Deferred
from instruments.isu.counter import PRINT_S
from sim.timebase import ticks
from station.config.isu import load_config
from station.racks.cigtf import CigtfRack
from station.racks.esg import EsgRack
from station.racks.isu import SimulatedRack

PROPERTY = settings(max_examples=150, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])

# grammar name -> (rack kind, instrument name on that rack)
INSTRUMENTS = {
    "table": ("isu", "table"), "patch_panel": ("isu", "patch_panel"),
    "counter": ("isu", "counter1"), "autocollimator": ("isu", "autocollimator1"),
    "bubble_levels": ("isu", "bubble_levels"), "oscillator": ("isu", "oscillator"),
    "fixture": ("cigtf", "fixture"), "dvm": ("cigtf", "dvm"),
    "gyro_power": ("cigtf", "gyro_power"), "setup_aids": ("cigtf", "setup_aids"),
    "processor": ("esg", "processor"),
    "head": ("esg", "head"), "turntable": ("esg", "turntable"),
    "theodolite": ("esg", "theodolite"), "console": ("esg", "console"),
}


def test_every_grammar_has_an_instrument_and_the_same_command_words():
    assert set(INSTRUMENTS) == set(GRAMMARS)
    for name in GRAMMARS:
        with built(name) as inst:
            assert set(inst.verbs) == set(GRAMMARS[name].words), name


class built:
    """The instrument of grammar ``name`` on a fresh rack (the counter wired to its gates)."""

    def __init__(self, name: str) -> None:
        kind, inst = INSTRUMENTS[name]
        if kind == "isu":
            self.rack: SimulatedRack | CigtfRack | EsgRack = SimulatedRack(load_config())
        elif kind == "cigtf":
            self.rack = CigtfRack(3)
        else:
            self.rack = EsgRack(3)
        self.inst: ByteInstrument = self.rack.serial[inst]
        if inst == "counter1":
            wire(self.rack.serial["patch_panel"], "OSC1", "X", "OSC2", "Z")

    def __enter__(self) -> ByteInstrument:
        return self.inst

    def __exit__(self, *exc) -> None:
        self.rack.close()


def wire(panel: ByteInstrument, *pairs: str) -> None:
    for line, inp in zip(pairs[::2], pairs[1::2], strict=True):
        assert panel.reply_to(f"CONN {line} C1 {inp}".encode()) == "OK"


def advance(inst: ByteInstrument, seconds: float) -> None:
    if ticks(seconds) > 0:
        inst.env.run(until=inst.env.now + ticks(seconds))


def lines_out(inst: ByteInstrument) -> list[str]:
    """The complete lines the instrument has sent since the last call (and forgets them)."""
    data = bytes(inst.output)
    inst.output.clear()
    return data.decode("ascii").splitlines()


def send(inst: ByteInstrument, line: str, seconds: float = 0.1) -> list[str]:
    inst.receive(line.encode() + b"\n")
    advance(inst, seconds)
    return lines_out(inst)


def judged(inst: ByteInstrument, grammar: Grammar, raw: bytes) -> str:
    """Send one line, judge the one reply it queued, empty the queue, let 5 ms pass."""
    assert inst.pending() == ()
    inst.receive(raw + b"\n")
    queued = inst.pending()
    assert len(queued) <= 1, (raw, queued)
    reply, deferred = None, False
    if queued:
        item = queued[0]
        if isinstance(item, Deferred):
            deferred = not item.event.triggered
            reply = None if deferred else item.event.value
        else:
            reply = item
    verdict = grammar.judge(raw, reply, deferred)
    inst.clear_output()
    advance(inst, 0.005)
    assert inst.internal_faults == []
    return verdict if verdict != "wrong" else f"wrong: {raw!r} -> {reply!r} (deferred {deferred})"


# ----------------------------------------------------------------------------- properties


@pytest.mark.parametrize("name", GRAMMARS)
def test_valid_commands_get_the_documented_reply(name):
    grammar = GRAMMARS[name]
    with built(name) as inst:

        @PROPERTY
        @given(st.randoms(use_true_random=False))
        def check(rng: random.Random) -> None:
            raw = " ".join(grammar.draw_valid(rng)).encode()
            assert grammar.classify(raw) == "valid"
            assert judged(inst, grammar, raw) == "accepted"

        check()


@pytest.mark.parametrize("name", GRAMMARS)
def test_mutated_commands_get_an_error_reply_never_ok_or_a_value(name):
    grammar = GRAMMARS[name]
    with built(name) as inst:

        @PROPERTY
        @given(st.randoms(use_true_random=False))
        def check(rng: random.Random) -> None:
            raw = grammar.draw_line(rng)
            assert judged(inst, grammar, raw) in ("accepted", "rejected")

        check()


@pytest.mark.parametrize("name", GRAMMARS)
def test_extra_argument_after_a_full_command_is_refused_without_effect(name):
    """Every command word, with all its arguments and one more, gets ERR 11 (usage)."""
    grammar = GRAMMARS[name]
    rng = random.Random(13)
    with built(name) as inst:
        for word, cmd in grammar.words.items():
            words = [word] + [a.draw(rng) for a in cmd.args]
            for _ in range(20):  # arguments the cross-argument rule accepts
                if cmd.valid_args(words[1:]):
                    break
                words = [word] + [a.draw(rng) for a in cmd.args]
            reply = inst.reply_to(" ".join(words + ["1"]).encode())
            assert isinstance(reply, str) and reply.startswith("ERR 11 usage: "), (word, reply)


@pytest.mark.parametrize("name", GRAMMARS)
def test_cls_drops_queued_replies_and_errors(name):
    """After a burst, *CLS answers OK next and the identity follows at once (issue 13: it
    arrived 2,750 lines later); the error queue is empty; nothing from the burst follows."""
    grammar = GRAMMARS[name]
    with built(name) as inst:

        @settings(max_examples=25, deadline=None)
        @given(st.integers(1, 3000), st.floats(0.0, 1.0))
        def check(burst: int, wait_s: float) -> None:
            inst.receive(b"FROB\n" + b"*IDN?\n" * (burst - 1))
            advance(inst, wait_s)
            lines_out(inst)
            inst.receive(b"*CLS\n*IDN?\nSYST:ERR?\n")
            advance(inst, 1.0)
            assert lines_out(inst) == ["OK", grammar.ident, "0 no error"]

        check()


@pytest.mark.parametrize("name", GRAMMARS)
def test_output_queue_is_bounded_and_overflow_is_an_error(name):
    """A flood of queries holds at most MAX_REPLIES replies; the lines beyond are not
    executed, 350 goes on the error queue once, and *CLS still clears everything."""
    grammar = GRAMMARS[name]
    with built(name) as inst:
        inst.receive(b"*IDN?\n" * 20_000)
        assert len(inst.pending()) == MAX_REPLIES
        inst.receive(b"*IDN?\n" * 100)
        overflow = [e for e in inst.errors if e.startswith("ERR 350 ")]
        assert len(overflow) == 1 and "queue overflow" in overflow[0]
        inst.receive(b"*CLS\n")  # executed although the queue is full
        assert inst.pending() == ("OK",)
        advance(inst, 1.0)
        assert lines_out(inst) == ["OK"]
        assert send(inst, "*IDN?") == [grammar.ident]


def test_lines_beyond_a_full_queue_are_not_executed():
    with built("table") as inst:
        inst.receive(b"PPR?\n" * MAX_REPLIES + b"PPR 7\n")
        advance(inst, 5.0)
        assert lines_out(inst) == ["1"] * MAX_REPLIES
        assert send(inst, "SYST:ERR?")[0].startswith("350 queue overflow")
        assert send(inst, "PPR?") == ["1"]


def test_flood_of_read_queries_holds_bounded_memory():
    """200,000 READ? on an operating counter (issue 13: 95 MB) queue 256 waiting replies."""
    with built("counter") as c:
        assert send(c, "PRESET 100000000") == ["OK"]  # 10^4 s gates: no reading comes
        assert send(c, "OPER") == ["OK"]
        c.receive(b"READ?\n" * 200_000)
        assert len(c.pending()) == MAX_REPLIES
        assert all(isinstance(r, Deferred) for r in c.pending())
        assert send(c, "*CLS") == ["OK"]
        c.receive(b"READ?\n*CLS\n" * 10_000)  # cancelled waiters are not kept
        assert len(c._waiters) <= 1


# ----------------------------------------------------------------------------- grammar


REFUSED = [
    # (grammar, line, code): each once a silently accepted form (issue 13)
    ("table", "STOP 2 3 4", 11),
    ("table", "STAT? 2 3", 11),
    ("table", "HOME 1", 11),
    ("table", "POS 1 +10", 11),
    ("table", "POS 2 1_0", 11),
    ("table", "POS 2 1e400", 11),
    ("table", "POS 2 1e20", 12),  # beyond ten turns: the modulo would lose the arcsec
    ("table", "PPR \u0663", 100),  # an Arabic-Indic digit: not ASCII
    ("table", "PPR \uff13", 100),  # a fullwidth digit
    ("counter", "PRESET 1_000", 11),
    ("counter", "PRESET +1000", 11),
    ("counter", "PRESET 1000.", 11),
    ("counter", "PRESET 0x3e8", 11),
    ("counter", "MODE X--Y", 11),
    ("counter", "MODE -XY", 11),
    ("counter", "OPER now", 11),
    ("counter", "READ? 1", 11),
    ("patch_panel", "CLR ALL", 11),
    ("patch_panel", "CONN G1+ C1 X Y", 11),
    ("autocollimator", "MEAS? 1", 11),
    ("autocollimator", "AIM 1e9 90", 12),
    ("bubble_levels", "LEV? X", 11),
    ("oscillator", "FREQ? 1", 11),
    ("oscillator", "DIV? 01.0", 11),
    ("fixture", "MOVE V 1_0", 11),
    ("fixture", "STAT? V", 11),
    ("dvm", "AVG? 10", 11),
    ("gyro_power", "PWR ON OFF", 11),
    ("processor", "GO +5", 11),
    ("processor", "THR 1_5", 11),
    ("head", "SPIN 45 ", 0),  # trailing blanks are no argument: accepted
    ("head", "SPIN \u00b2", 100),
    ("turntable", "TILT 1 2", 11),
    ("console", "SPIN UP NOW", 11),
    ("theodolite", "READ? READ?", 11),
    ("table", "*IDN? x", 11),
    ("table", "SYST:ERR? 1", 11),
    ("table", "*CLS 1", 11),
]


@pytest.mark.parametrize(("name", "line", "code"), REFUSED)
def test_strict_grammar(name, line, code):
    with built(name) as inst:
        reply = inst.reply_to(line.encode())
        if code == 0:
            assert reply == "OK"
        else:
            assert isinstance(reply, str) and reply.startswith(f"ERR {code} "), reply
            assert inst.errors[-1] == reply
        assert GRAMMARS[name].classify(line.encode()) == ("valid" if code == 0 else "invalid")


def test_stop_with_extra_axes_stops_nothing():
    with built("table") as t:
        for ax in (2, 3, 4):
            assert send(t, f"RATE {ax} 10") == ["OK"]
        advance(t, 5.0)
        assert send(t, "STOP 2 3 4") == ["ERR 11 usage: STOP [<axis>]"]
        advance(t, 5.0)
        assert send(t, "STAT?") == ["HOLD,ROTATING,ROTATING,ROTATING"]


def test_real_arguments_in_every_documented_form():
    with built("table") as t:
        for text, deg in (("12.5", 12.5), ("-0.25", 359.75), (".5", 0.5), ("7.", 7.0),
                          ("1.25e1", 12.5), ("125E-1", 12.5), ("0003", 3.0), ("-0", 0.0)):
            assert send(t, f"POS 2 {text}") == ["OK"]
            advance(t, 60.0)
            got = float(send(t, "POS? 2")[0])
            assert abs((got - deg + 180.0) % 360.0 - 180.0) < 2e-3, text  # resolver error


# ----------------------------------------------------------------------------- counters


@pytest.fixture
def isu():
    rack = SimulatedRack(load_config())
    yield rack
    rack.close()


def test_preset_the_print_out_cannot_sustain_is_refused_at_oper(isu):
    """PRESET 1 on the 1 MHz gate would print a million readings a second (issue 13)."""
    c, panel = isu.serial["counter1"], isu.serial["patch_panel"]
    wire(panel, "OSC2", "X", "OSC1", "Z")  # measure Z: the gate is 1 MHz clock ticks
    assert send(c, "PRESET 1") == ["OK"]
    reply = send(c, "OPER")[0]
    m = re.fullmatch(r"ERR 25 gate of 1 pulses lasts (\S+) s, shorter than the 0.02 s "
                     r"print-out: preset at least ([0-9]+)", reply)
    assert m is not None, reply
    assert float(m.group(1)) == pytest.approx(1e-6, rel=1e-6)
    least = int(m.group(2))
    assert least == round(PRINT_S * 1e6)
    assert send(c, "STATE?") == ["STBY"]
    assert send(c, f"PRESET {least - 1}") == ["OK"]
    assert send(c, "OPER")[0].startswith("ERR 25 ")
    assert send(c, f"PRESET {least}") == ["OK"]
    assert send(c, "OPER") == ["OK"]
    # the gate is 20 ms of S1^T: 20 ms x 10 kHz of S2^T, the readings 20 ms apart
    c.receive(b"READ?\nREAD?\nREAD?\n")
    advance(c, 1.0)
    assert lines_out(c) == [str(round(PRINT_S * 1e4))] * 3


def test_gate_shortened_while_counting_is_a_print_overrun(isu):
    """A TROT gate accepted with the table at rest becomes too short once the table turns:
    the counter stops, a waiting READ? gets the cause, the error queue says it too, and
    the work per simulated second stays bounded."""
    c, panel, table = isu.serial["counter1"], isu.serial["patch_panel"], isu.serial["table"]
    wire(panel, "OSC1", "X", "TROT", "Z")
    assert send(table, "PPR 3600") == ["OK"]
    assert send(c, "PRESET 2") == ["OK"]
    assert send(c, "OPER") == ["OK"]
    c.receive(b"READ?\n" * 40)
    assert send(table, "RATE 2 20") == ["OK"]  # at 20 deg/s, 200 pulses/s: 2 in 0.01 s
    advance(c, 10.0)
    out = lines_out(c)
    # the gates (0.2 deg) shorten as the table accelerates at 10 deg/s^2: the k-th, from
    # 0.2 (k-1) to 0.2 k deg, lasts sqrt(0.04 k) - sqrt(0.04 (k-1)) s, 20 ms or more while
    # k <= 25; the 26th is too short to print
    readings, overruns = out[:25], out[25:]
    assert len(overruns) == 15 and len(set(overruns)) == 1  # every waiting READ? is told
    overrun = overruns[0]
    # the first gate opens on the first edge, T0 after the ramp began: 5 T^2 grows by 0.2
    # deg per gate from there (1 us ticks; the resolver's cyclic error is ~3e-4 deg)
    d = [int(r) * 1e-6 for r in readings]
    t = (0.04 - d[0] ** 2) / (2 * d[0])
    theta0 = 5 * t * t
    for k, dk in enumerate(d, start=1):
        t += dk
        assert 5 * t * t - theta0 == pytest.approx(0.2 * k, abs=1e-3)
        assert dk >= PRINT_S
    m = re.fullmatch(r"ERR 25 print overrun: gate of 2 pulses lasted (\S+) s, shorter than "
                     r"the 0.02 s print-out; counter in standby", overrun)
    assert m is not None, overrun
    assert float(m.group(1)) == pytest.approx(1.04**0.5 - 1.0, rel=1e-2)
    assert c.n_readings <= 10.0 / PRINT_S
    assert send(c, "STATE?") == ["STBY"]
    assert send(c, "SYST:ERR?")[0].startswith("25 print overrun")


def test_read_in_standby_is_refused_and_standby_answers_a_waiting_read(isu):
    c = isu.serial["counter1"]
    assert send(c, "READ?") == ["ERR 26 no reading: counter in standby"]
    wire(isu.serial["patch_panel"], "OSC1", "X", "OSC2", "Z")
    assert send(c, "PRESET 100000000") == ["OK"]
    assert send(c, "OPER") == ["OK"]
    c.receive(b"READ?\nSTBY\n")
    advance(c, 1.0)
    assert lines_out(c) == ["ERR 26 no reading: counter set to standby by STBY", "OK"]


def test_cls_cancels_a_waiting_read(isu):
    c = isu.serial["counter1"]
    wire(isu.serial["patch_panel"], "OSC1", "X", "OSC2", "Z")
    assert send(c, "PRESET 100000000") == ["OK"]
    assert send(c, "OPER") == ["OK"]
    c.receive(b"READ?\n*IDN?\n*CLS\n*IDN?\n")
    advance(c, 1.0)
    assert lines_out(c) == ["OK", "ISU-LAB,FC-1,C1,1.0"]
    assert send(c, "STATE?") == ["OPER"]


# ----------------------------------------------------------------------------- internal faults


def test_internal_fault_is_err_200_naming_what_failed_not_a_bad_argument(isu, monkeypatch):
    t = isu.serial["table"]

    def broken(axis, t):
        raise ValueError("resolver table index out of range")

    monkeypatch.setattr(isu.world.table, "resolver", broken)
    reply = send(t, "POS? 2")
    assert reply == ["ERR 200 internal: POS? failed: ValueError: resolver table index out "
                     "of range"]
    assert t.internal_faults == [reply[0][8:]]
    assert send(t, "POS? x") == ["ERR 11 axis must be an integer, got 'x'"]  # still the host's
    assert send(t, "*IDN?") == ["ISU-LAB,TT-4AX,0,1.0"]


def test_internal_fault_while_counting_stops_the_counter_and_answers_the_read(isu, monkeypatch):
    c = isu.serial["counter1"]
    wire(isu.serial["patch_panel"], "OSC1", "X", "OSC2", "Z")
    assert send(c, "PRESET 10000") == ["OK"]
    assert send(c, "OPER") == ["OK"]
    line = isu.world.line("OSC1")

    def broken(t0, t1):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(line, "count", broken)
    c.receive(b"READ?\n")
    advance(c, 3.0)
    out = lines_out(c)
    assert out == ["ERR 200 internal: counting (OPER) failed: ZeroDivisionError: float "
                   "division by zero"]
    assert send(c, "STATE?") == ["STBY"]


def test_internal_fault_in_a_deferred_measurement(isu, monkeypatch):
    ac = isu.serial["autocollimator1"]

    def broken():
        raise FloatingPointError("overflow in mirror normal")

    monkeypatch.setattr(ac, "measure", broken)
    assert send(ac, "MEAS?", 1.0) == [
        "ERR 200 internal: MEAS? failed: FloatingPointError: overflow in mirror normal"]


def test_internal_fault_text_is_one_printable_line(isu, monkeypatch):
    t = isu.serial["table"]

    def broken(axis, t):
        raise RuntimeError("bad\nstate \u00b0" + "x" * 500)

    monkeypatch.setattr(isu.world.table, "resolver", broken)
    (reply,) = send(t, "POS? 1")
    assert reply.startswith("ERR 200 internal: POS? failed: RuntimeError: bad?state ?xxx")
    assert len(reply) <= 8 + 160


# ----------------------------------------------------------------------------- CIGTF, ESG


def test_fixture_drive_fault_cleared_by_cls():
    with built("fixture") as fx:
        fx.fail_moves = True  # type: ignore[attr-defined]
        assert send(fx, "MOVE V 10") == ["OK"]
        advance(fx, 30.0)
        assert send(fx, "STAT?") == ["FAULT"]
        assert send(fx, "MOVE V 20") == ["ERR 17 drive fault: clear with *CLS"]
        fx.fail_moves = False  # type: ignore[attr-defined]
        assert send(fx, "*CLS") == ["OK"]
        assert send(fx, "STAT?") == ["HOLD"]
        assert send(fx, "SYST:ERR?") == ["0 no error"]


def test_processor_stream_flows_after_cls_drops_the_go_ok():
    """The first data line waits for its GO's OK; a *CLS that drops that OK lets it go."""
    with built("processor") as p:
        p.receive(b"GO 3\n*CLS\n")
        advance(p, 30.0)
        out = lines_out(p)
        assert out[0] == "OK"  # the *CLS's; the GO's was dropped with the queue
        assert len(out) == 4
        assert all(re.fullmatch(r"[0-9]{7}( [0-9]{7}){5}", x) for x in out[1:])

@pytest.mark.parametrize(("name", "query", "wait_s"), [("dvm", "AVG?", 15.0),
                                                       ("autocollimator", "MEAS?", 1.0)])
def test_cls_abandons_a_measurement_in_progress(name, query, wait_s):
    with built(name) as inst:
        inst.receive(f"{query}\n*CLS\n*IDN?\n".encode())
        advance(inst, wait_s)
        assert lines_out(inst) == ["OK", GRAMMARS[name].ident]
        assert send(inst, query, wait_s) != []  # and the next one is measured
