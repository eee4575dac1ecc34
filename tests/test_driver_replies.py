"""Strict driver replies (issue 13): every reply parsed against the syntax the protocol
defines and the instrument's range, replies matched to their commands, and the ESG data
lines checked against Appendix A.

The oracle (tests/reply_specs.py) is written from the instruments' format strings,
independently of station/drivers/replies.py.
"""

from __future__ import annotations

import inspect
import random

import pytest
import serial
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from reply_specs import (
    IDENT,
    SPECS,
    ScriptedPort,
    _call,
    _outcome,
    on_script,
    run_line_checker,
    run_lines,
    run_one,
)

import instruments.esg as inst_esg
import instruments.isu.counter as inst_counter
from sim.esg.mount import MountSpec
from sim.timebase import ticks
from station.drivers import cigtf, esg, replies
from station.drivers.isu import (
    autocollimator,
    bubble_level,
    counter,
    oscillator,
    patch_panel,
    table,
)
from station.drivers.isu.bubble_level import BubbleLevelDriver
from station.drivers.isu.counter import CounterDriver
from station.drivers.isu.oscillator import OscillatorDriver
from station.drivers.isu.table import TableDriver
from station.drivers.serial_base import SerialDriver
from station.errors import (
    DriverError,
    InstrumentRefused,
    LinkTimeout,
    MalformedReply,
    ReadingOutOfRange,
    current_step,
)

BOUNDED = settings(max_examples=40, deadline=None, derandomize=True,
                   suppress_health_check=[HealthCheck.too_slow])
SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


# -------------------------------------------------------------------------------------- coverage


def _parsers() -> set[str]:
    """Class.method of every driver method that reads a reply (through ask)."""
    out = set()
    for mod in (autocollimator, bubble_level, cigtf, counter, esg, oscillator, patch_panel,
                table):
        for cname, cls in inspect.getmembers(mod, inspect.isclass):
            if not issubclass(cls, SerialDriver) or cls.__module__ != mod.__name__:
                continue
            for mname, fn in vars(cls).items():
                if callable(fn) and "self.ask(" in inspect.getsource(fn):
                    out.add(f"{cname}.{mname}")
    return out


def test_every_reply_parser_has_a_specification():
    covered = {s.name.split("(")[0] for s in SPECS}
    missing = {p for p in _parsers() if p not in covered and not p.startswith("_")}
    # the processor's data lines have their own targets (run_lines, run_line_checker)
    assert missing == set(), missing
    assert {"SerialDriver.identify", "SerialDriver.command"} <= covered


# ------------------------------------------------------------------------------------ properties


@pytest.mark.parametrize("spec", SPECS, ids=[s.name for s in SPECS])
@BOUNDED
@given(seed=SEEDS)
def test_well_formed_replies_parse_to_their_exact_value(spec, seed):
    rng = random.Random(seed)
    drv = spec.make()
    plan = spec.plan(rng, drv)
    texts = [r.generate(rng) for r in plan.replies]
    data = [(t + "\n").encode() for t in texts]
    for reply, d in zip(plan.replies, data, strict=True):
        drv.port.answer(reply.command, d)
    want = _outcome(spec, plan, data)
    got = _call(drv, plan)
    assert got == want, (texts, got, want)
    assert drv.unexpected == 0


@pytest.mark.parametrize("spec", SPECS, ids=[s.name for s in SPECS])
@BOUNDED
@given(seed=SEEDS)
def test_mutated_replies_are_refused_or_read_exactly(spec, seed):
    # no builtin exception, no value from a malformed reply, no leftover taken later
    assert run_one(spec, random.Random(seed)) in ("accepted", "rejected")


@BOUNDED
@given(seed=SEEDS)
def test_esg_data_lines_are_checked_against_appendix_a(seed):
    assert run_line_checker(random.Random(seed)) in ("accepted", "rejected")


@BOUNDED
@given(seed=SEEDS)
def test_esg_stream_lines_never_raise_and_leftovers_never_disturb(seed):
    assert run_lines(random.Random(seed)) in ("accepted", "rejected")


@BOUNDED
@given(v=st.floats(allow_nan=False, allow_infinity=False, min_value=-1e12, max_value=1e12),
       n=st.integers(min_value=1, max_value=7))
def test_every_number_an_instrument_prints_is_its_grammar(v, n):
    for field, text in ((replies.fixed("x", n, -1e12, 1e12), f"{v:.{n}f}"),
                        (replies.general("x", -1e12, 1e12), f"{v:g}"),
                        (replies.integer("x", -10**12, 10**12), str(int(v))),
                        (replies.scientific("x", 0.0, 1e12), f"{abs(v):.1E}")):
        form = replies.Form([field])
        assert form.matches(text), text
        assert form.parse(text) == (field.convert(text),)
        for junk in (text + "0", "+" + text, text.replace("-", ""), text + "_1", " " + text):
            if junk != text and not form.matches(junk):
                continue
            # what still matches must be what the format prints for its value
            assert junk in (f"{float(junk):.{n}f}", f"{float(junk):g}", str(int(float(junk))),
                            f"{float(junk):.1E}")


# ------------------------------------------------------------------------- the cases of issue 13


def scripted(cls, **kw):
    return on_script(cls, IDENT[cls], **kw)


@pytest.fixture
def step():
    token = current_step.set("Chart III-2 step 4")
    yield "Chart III-2 step 4"
    current_step.reset(token)


def test_a_zero_frequency_is_refused_not_divided_by(step):
    osc = scripted(OscillatorDriver, name="oscillator")
    osc.port.answer("DIV? 2", b"500\n")
    osc.port.answer("FREQ?", b"000000.0\n")  # leading zeros: not what the panel prints
    with pytest.raises(MalformedReply) as e:
        osc.s_t(2)
    msg = str(e.value)
    assert msg.startswith("oscillator (loop://) during Chart III-2 step 4: ")
    assert e.value.command == "FREQ?" and "'000000.0'" in msg and e.value.step == step
    osc.port.answer("DIV? 2", b"500\n")
    osc.port.answer("FREQ?", b"0.0\n")  # well-formed, but no oscillator runs at 0 Hz
    with pytest.raises(ReadingOutOfRange, match=r"nominal frequency, Hz 0 outside"):
        osc.s_t(2)


def test_a_garbled_table_reading_names_table_command_and_step(step):
    tb = scripted(TableDriver, clock=None)
    tb.port.answer("POS? 1", b"89.9999$72\n")
    with pytest.raises(MalformedReply) as e:
        tb.position(1)
    assert e.value.instrument == "table" and e.value.command == "POS? 1"
    assert e.value.lines == ("89.9999$72",)
    assert "unexpected reply '89.9999$72' to 'POS? 1'" in str(e.value)
    assert "during Chart III-2 step 4" in str(e.value)


@pytest.mark.parametrize("reply, error", [
    (b"680.0 12.30\n", MalformedReply),  # one decimal, not the levels' two
    (b"680.00 12.30\n", ReadingOutOfRange),  # a lost decimal point: beyond +/-120 arcsec
    (b"6800 12.30\n", MalformedReply),
    (b"nan 12.30\n", MalformedReply),
    (b"inf 12.30\n", MalformedReply),
    (b"1_0.00 12.30\n", MalformedReply),
    (b"+6.80 12.30\n", MalformedReply),
    (b"6.80 12.30 0.00\n", MalformedReply),  # an extra field
    (b"6.80\n", MalformedReply),
    (b"-121.50 0.00\n", ReadingOutOfRange),
])
def test_bubble_levels_refuse_what_the_levels_cannot_say(reply, error):
    bl = scripted(BubbleLevelDriver, name="bubble_levels")
    bl.port.answer("LEV?", reply)
    with pytest.raises(error) as e:
        bl.corrections()
    assert e.value.instrument == "bubble_levels" and e.value.command == "LEV?"


def test_a_lost_sign_is_well_formed_and_read_as_sent():
    # what no syntax can catch: the plausibility checks of the procedures have to
    bl = scripted(BubbleLevelDriver, name="bubble_levels")
    bl.port.answer("LEV?", b"6.80 12.30\n")
    assert bl.corrections() == (6.8, 12.3)
    bl.port.answer("LEV?", b"-0.00 -120.90\n")
    assert bl.corrections() == (0.0, -120.9)


@pytest.mark.parametrize("reply", [b"1_0\n", b"+10\n", b"010\n", b"-0\n", b"10.0\n", b"1e3\n",
                                   b" 10\n", b"10 \n", b"\xd9\xa1\n", b"-5\n"])
def test_counter_readings_are_plain_integers(reply):
    c = scripted(CounterDriver, name="counter3")
    c.set_mode("measure X-Y")  # clock ticks: never negative
    c.port.answer("READ?", reply)
    with pytest.raises(DriverError):
        c.read(timeout=1.0)
    c.port.answer("READ?", b"123456789012\n")
    assert c.read(timeout=1.0) == 123456789012


def test_a_negative_count_is_refused_only_where_it_cannot_be():
    c = scripted(CounterDriver, name="counter3")
    c.set_mode("measure Z")  # X-Y may be negative
    c.port.answer("READ?", b"-5\n")
    assert c.read(timeout=1.0) == -5
    c.set_mode("measure X-Y")
    c.port.answer("READ?", b"-5\n")
    with pytest.raises(ReadingOutOfRange, match="negative count of clock ticks"):
        c.read(timeout=1.0)


def test_arguments_a_command_cannot_carry_are_refused_before_sending():
    c = scripted(CounterDriver, name="counter3")
    for bad in (2.5, float("nan"), float("inf"), 0, 10**11 + 1, "x"):
        with pytest.raises(DriverError, match="preset must be a whole number"):
            c.set_preset(bad)
    for cmd in ("PRESET 1\nOPER", "MODE Z\r", "READ?\x00", "CONN G1 C1 X\u00e9", ""):
        with pytest.raises(DriverError, match="printable ASCII"):
            c.command(cmd)
    assert c.port.written == []


# ------------------------------------------------------------------- replies matched to commands


def test_a_stray_line_waiting_before_a_command_is_reported_and_dropped(caplog):
    tb = scripted(TableDriver, clock=None)
    tb.port.input += b"123.4560000\n"  # a well-formed reading nobody asked for
    tb.port.answer("POS? 2", b"45.0000000\n")
    assert tb.position(2) == 45.0
    assert tb.unexpected == 1 and list(tb.unexpected_lines) == ["123.4560000"]
    assert "table (loop://): line '123.4560000' unexpected: waiting before 'POS? 2'" \
        in caplog.text


def test_an_extra_line_after_a_reply_never_shifts_the_next_one():
    tb = scripted(TableDriver, clock=None)
    tb.port.answer("POS? 2", b"45.0000000\n46.0000000\n")  # one reply too many
    tb.port.answer("POS? 3", b"90.0000000\n")
    tb.port.answer("POS? 4", b"180.0000000\n")
    assert (tb.position(2), tb.position(3), tb.position(4)) == (45.0, 90.0, 180.0)
    assert list(tb.unexpected_lines) == ["46.0000000"]


def test_a_line_of_another_form_before_the_reply_is_dropped():
    tb = scripted(TableDriver, clock=None)
    tb.port.answer("ILCK?", b"OK\n\xff\xfe\nCLOSED\n")
    assert tb.interlock() == "CLOSED"
    assert list(tb.unexpected_lines) == ["OK", "\\xff\\xfe"]


def test_after_a_silent_timeout_the_late_reply_is_skipped_behind_the_identity():
    tb = scripted(TableDriver, clock=None)
    tb.port.answer("POS? 2", b"")  # nothing within the timeout
    with pytest.raises(LinkTimeout, match=r"no reply to 'POS\? 2' within 5 s"):
        tb.position(2)
    assert tb.out_of_step
    tb.port.input += b"123.4560000\n"  # the late reply arrives
    tb.port.answer("POS? 2", b"45.0000000\n")
    assert tb.position(2) == 45.0  # not 123.456
    assert tb.port.written[-3:] == ["*CLS", "*IDN?", "POS? 2"]
    assert list(tb.unexpected_lines) == ["123.4560000", "OK"] and not tb.out_of_step


def test_a_reply_that_lost_its_end_of_line_needs_no_resynchronisation():
    tb = scripted(TableDriver, clock=None)
    tb.port.answer("POS? 2", b"45.0000000")  # the instrument answered: \n lost
    with pytest.raises(LinkTimeout, match=r"partial reply b'45.0000000'"):
        tb.position(2)
    assert not tb.out_of_step
    tb.port.answer("POS? 2", b"46.0000000\n")
    assert tb.position(2) == 46.0 and "*CLS" not in tb.port.written


def test_a_babbling_link_is_an_error_not_a_hang():
    tb = scripted(TableDriver, clock=None)
    tb.port.answer("POS? 2", b"x\n" * 100 + b"45.0000000\n")
    with pytest.raises(MalformedReply, match="among 64 lines"):
        tb.position(2)


def test_an_over_long_line_is_dropped_whole():
    tb = scripted(TableDriver, clock=None)
    tb.port.answer("POS? 2", b"4" * 3000 + b"5.0000000\n" + b"45.0000000\n")
    assert tb.position(2) == 45.0
    assert tb.unexpected_lines[-1].endswith("... (over-long line)")


class BrokenPort(ScriptedPort):
    """A link that fails the way a closed pty does: even setting its timeout raises."""

    broken = False

    @property
    def timeout(self):
        return 5.0

    @timeout.setter
    def timeout(self, value):
        if self.broken:
            raise serial.SerialException("Could not configure port: (5, 'Input/output error')")


def test_a_link_that_fails_mid_exchange_is_a_driver_error_naming_it(step):
    tb = scripted(TableDriver, clock=None)
    tb.port = BrokenPort(IDENT[TableDriver])
    tb.port.answer("POS? 2", b"45.0000000\n")
    assert tb.position(2) == 45.0
    tb.port.broken = True
    with pytest.raises(DriverError) as e:
        tb.position(2)
    assert type(e.value) is DriverError and e.value.command == "POS? 2"
    assert str(e.value).startswith("table (loop://) during Chart III-2 step 4: link failed "
                                   "during 'POS? 2': Could not configure port")


def test_identity_must_be_the_drivers_model():
    tb = scripted(TableDriver, clock=None)
    tb.port.answer("*IDN?", b"ISU-LAB,FC-1,C1,1.0\n")  # the table's cable on a counter
    with pytest.raises(MalformedReply, match="expected 'ISU-LAB,TT-4AX,<unit>,<version>'"):
        tb.identify()
    any_drv = scripted(SerialDriver, name="counter1")
    any_drv.port.ident = "ISU-LAB,FC-1,C1,1.0"
    assert any_drv.identify() == "ISU-LAB,FC-1,C1,1.0"


# ------------------------------------------------------------------------- on the simulated rack


def test_stray_line_from_an_instrument_leaves_the_driver_in_step(station, rack):
    inst = rack.serial["table"]
    tb = station.table
    tb.move(2, 30.0)
    tb.wait_still()
    inst._emit(b"123.4560000\n")  # an unsolicited line on the wire
    got = [tb.position(2) for _ in range(3)]
    assert all(abs(g - 30.0) < 5 / 3600 for g in got), got  # resolver error: ~1 arcsec
    assert tb.unexpected == 1 and tb.unexpected_lines[-1] == "123.4560000"


def test_late_reply_after_a_timeout_is_never_taken_for_the_next(station, rack):
    inst = rack.serial["bubble_levels"]
    bl = station.bubble_levels
    seen: list[bytes] = []
    inst.listeners.append(seen.append)
    inst.latency = ticks(6.0)  # slower than the driver's 5 s timeout
    with pytest.raises(LinkTimeout, match=r"no reply to 'LEV\?' within 5 s"):
        bl.corrections()
    inst.latency = ticks(0.002)  # (the late reply is already on its way)
    c = bl.corrections()
    # the resynchronising *CLS empties the output queue (the late LEV? reply never leaves,
    # as on a SCPI device); its OK and the known identity mark the end of stale output
    cls_ok, ident, fresh = (s.decode().strip() for s in seen)
    assert (cls_ok, ident) == ("OK", "ISU-LAB,BL-2,0,1.0")
    assert c == tuple(float(x) for x in fresh.split())
    assert list(bl.unexpected_lines) == ["OK"]
    bl.corrections()  # in step again: a plain exchange, one reply
    assert len(seen) == 4 and bl.unexpected == 1


def test_refusals_name_the_command(station):
    station.table.set_pulses_per_rev(90)
    with pytest.raises(InstrumentRefused) as e:
        station.table.set_pulses_per_rev(5000)
    assert e.value.code == 12 and e.value.command == "PPR 5000"
    assert "instrument error 12 on 'PPR 5000'" in str(e.value)


# ------------------------------------------------------------------- ranges from the instruments


def test_driver_ranges_are_the_instruments(cfg, rack):
    i = cfg.instruments
    assert bubble_level.RANGE_ARCSEC == i.bubble_level.range_arcsec
    assert bubble_level.READING_SLACK_ARCSEC >= 5 * i.bubble_level.noise_arcsec
    assert autocollimator.FOV_DEG == i.autocollimator.fov_deg
    assert autocollimator.ZENITH_RANGE_DEG == tuple(i.autocollimator.zenith_range_deg)
    assert autocollimator.READING_SLACK_DEG * 3600 >= 5 * i.autocollimator.noise_arcsec
    assert table.TRUNNION_RANGE_DEG == tuple(cfg.table.trunnion_range_deg)
    assert table.MAX_RATE_DEG_S == cfg.table.max_rate_deg_s
    assert counter.QUEUE == inst_counter.MAX_QUEUE
    assert set(patch_panel.LINES) == set(rack.world.lines)
    assert esg.REVOLUTIONS == inst_esg.REVOLUTIONS and esg.MAX_LINES == inst_esg.MAX_LINES
    assert esg.TILT_LIMIT_DEG == MountSpec().tilt_limit_deg
    # the counter's preset limit: the instrument takes 10^11 and refuses one more
    c = rack.serial["counter1"]
    assert c.reply_to(f"PRESET {counter.MAX_PRESET}".encode()) == "OK"
    refused = c.reply_to(f"PRESET {counter.MAX_PRESET + 1}".encode())
    assert refused.startswith("ERR 12 ") and c.preset == counter.MAX_PRESET


@pytest.mark.parametrize("axis, reply, value", [
    (2, b"360.0000000", 360.0),  # 359.99999996 printed with 7 decimals
    (2, b"-0.0000000", 0.0),
    (2, b"360.0000001", None),
    (2, b"-0.0000001", None),
    (1, b"95.0100000", 95.01),  # a reading a little past the trunnion's limit
    (1, b"-5.0100001", None),
    (1, b"180.0000000", None),
])
def test_readings_at_the_ends_of_a_range(axis, reply, value):
    tb = scripted(TableDriver, clock=None)
    tb.port.answer(f"POS? {axis}", reply + b"\n")
    if value is None:
        with pytest.raises(ReadingOutOfRange, match=f"axis {axis} reading, deg"):
            tb.position(axis)
    else:
        assert tb.position(axis) == value


def test_the_default_station_reads_within_every_range(station):
    for p in station.table.positions():  # at home: about 0, or just below 360
        assert min(abs(p), abs(360.0 - p)) < 5 / 3600, p
    assert station.oscillator.s_t(1) == 1e-6 and station.oscillator.s_t(2) == 1e-4
    assert station.bubble_levels.corrections() is not None
    assert station.patch_panel.lines() == sorted(station.patch_panel.lines())
