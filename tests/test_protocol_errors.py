"""Protocol errors: every instrument refuses what it cannot do with its own error reply, the
drivers turn those replies into errors naming the instrument (and the procedure step), and no
garbage on a link ever crashes the simulator or desynchronises a driver."""

from __future__ import annotations

import math

import can
import pytest

from config.dbc import load_dbc
from instruments.isu.autocollimator import angles
from station.config.isu import SERIAL_INSTRUMENTS
from station.errors import DriverError, InstrumentRefused, LinkTimeout, current_step

IDENT = {
    "table": "ISU-LAB,TT-4AX,0,1.0",
    "patch_panel": "ISU-LAB,PATCH-PANEL,0,1.0",
    **{f"counter{i}": f"ISU-LAB,FC-1,C{i},1.0" for i in range(1, 7)},
    **{f"autocollimator{i}": f"ISU-LAB,AC-2,{i},1.0" for i in (1, 2)},
    "bubble_levels": "ISU-LAB,BL-2,0,1.0",
    "oscillator": "ISU-LAB,MO-5M,0,1.0",
}


def test_every_serial_instrument_is_covered():
    assert set(IDENT) == set(SERIAL_INSTRUMENTS)


def driver(st, name: str):
    if name.startswith("counter"):
        return st.counters[int(name.removeprefix("counter"))]
    if name.startswith("autocollimator"):
        return st.autocollimators[int(name.removeprefix("autocollimator"))]
    return getattr(st, name)


def exchange(drv, line: bytes) -> bytes:
    """Write raw bytes and return the next reply line as it came off the wire."""
    drv.port.write(line)
    return drv.port.read_until(b"\n")


def snapshot(st, name: str) -> tuple:
    """What a refused command must leave unchanged, read back over the wire."""
    d = driver(st, name)
    if name == "table":
        return (d.status(), d.positions(), d.rate(2), d.query("PPR?"))
    if name == "patch_panel":
        return tuple(d.connection(c, i) for c in range(1, 7) for i in "XYZ")
    if name.startswith("counter"):
        return (d.query("MODE?"), d.query("PRESET?"), d.state(), d.queued())
    if name.startswith("autocollimator"):
        return d.pointing()
    if name == "oscillator":
        return (d.nominal_hz(), d.divider(1), d.divider(2))
    return ()  # the bubble levels keep no settings


def assert_works(st, rack, name: str) -> None:
    """The instrument answers *IDN? and still makes a real measurement."""
    d = driver(st, name)
    assert d.identify() == IDENT[name]
    if name == "table":
        t0 = st.clock.now()
        st.table.move(1, 3.0)
        st.table.wait_still()
        assert st.clock.now() > t0
        assert st.table.position(1) == pytest.approx(3.0, abs=1e-3)
        assert st.table.status() == ["HOLD"] * 4
    elif name == "patch_panel":
        d.connect("G1+", 4, "X")
        assert d.connection(4, "X") == "G1+"
        d.disconnect(4, "X")
        assert d.connection(4, "X") is None
    elif name.startswith("counter"):
        n = int(name.removeprefix("counter"))
        # measure Z: 1 MHz clock ticks (S1^T) in 200 pulses of S2^T (20 ms, one print-out)
        st.patch_panel.connect("OSC1", n, "X")
        st.patch_panel.connect("OSC2", n, "Z")
        d.set_mode("measure Z")
        d.set_preset(200)
        d.operate()
        ratio = st.oscillator.divider(2) // st.oscillator.divider(1)
        assert d.read(timeout=1.0) == 200 * ratio
        d.standby()
    elif name.startswith("autocollimator"):
        true = angles(rack.world.mirror_normals(rack.world.now)[1])  # mirror 2, horizontal
        az, zen = (math.degrees(a) for a in true)
        d.aim(az, zen)
        m = d.measure()
        assert m is not None
        assert m[0] == pytest.approx(az, abs=0.003)
        assert m[1] == pytest.approx(zen, abs=0.003)
    elif name == "bubble_levels":
        true = [math.degrees(c) * 3600 for c in rack.serial["bubble_levels"].corrections()]
        got = d.corrections()
        assert got == pytest.approx(true, abs=1.5)
    elif name == "oscillator":
        assert d.nominal_hz() == rack.cfg.oscillator.nominal_hz
        assert d.divider(2) == rack.cfg.oscillator.s2_divider
        assert d.status() == "LOCKED"


# ----------------------------------------------------------------------------- serial


@pytest.mark.parametrize("name", SERIAL_INSTRUMENTS)
def test_unknown_command_gets_err_10_and_driver_names_instrument(station, rack, name):
    d = driver(station, name)
    assert exchange(d, b"FROB 1 2\n") == b"ERR 10 unknown command 'FROB'\n"
    with pytest.raises(InstrumentRefused) as e:
        d.query("WIBBLE?")
    assert e.value.code == 10
    assert e.value.instrument == name
    assert str(e.value).startswith(f"{name} (sim://{name}")
    assert "WIBBLE?" in str(e.value)
    assert_works(station, rack, name)


BAD_ARGUMENTS = [
    # (instrument, command, error code)
    ("table", "POS 1", 11),
    ("table", "POS 1 2 3", 11),
    ("table", "POS one 10", 11),
    ("table", "POS 1 ten", 11),
    ("table", "POS 1 nan", 11),
    ("table", "POS 1 -inf", 11),
    ("table", "POS 5 10", 12),
    ("table", "POS 0 10", 12),
    ("table", "POS 1 120", 13),  # trunnion outside its range
    ("table", "RATE 2", 11),
    ("table", "RATE 1 5", 12),  # the trunnion cannot rotate continuously
    ("table", "RATE 2 25", 13),  # above the rate limit
    ("table", "RATE 2 NaN", 11),
    ("table", "RAMP 2 5", 11),
    ("table", "RAMP 2 50 10", 13),  # above the acceleration limit
    ("table", "RAMP 2 0 10", 13),
    ("table", "PPR 0", 12),
    ("table", "PPR 3601", 12),
    ("table", "PPR 1.5", 11),
    ("table", "STOP 7", 12),
    ("table", "POS?", 11),
    ("table", "POS? 9", 12),
    ("table", "RATE? x", 11),
    ("table", "STAT? 5", 12),
    ("patch_panel", "CONN G1+ C1", 11),
    ("patch_panel", "CONN NOPE C1 X", 12),
    ("patch_panel", "CONN G1+ C7 X", 12),
    ("patch_panel", "CONN G1+ C1 W", 12),
    ("patch_panel", "DISC C1", 11),
    ("patch_panel", "CONN? C0 X", 12),
    ("counter1", "MODE", 11),
    ("counter2", "MODE W", 11),
    ("counter3", "PRESET", 11),
    ("counter4", "PRESET 0", 12),
    ("counter5", "PRESET -5", 12),
    ("counter6", "PRESET 1e5", 11),
    ("counter1", "PRESET nan", 11),
    ("counter2", "PRESET 12.5", 11),
    ("counter3", "PRESET 100000000001", 12),
    ("counter4", "PRESET 10 20", 11),
    ("counter5", "OPER", 21),  # nothing patched to its inputs
    ("autocollimator1", "AIM 10", 11),
    ("autocollimator2", "AIM 10 90 5", 11),
    ("autocollimator1", "AIM east 90", 11),
    ("autocollimator2", "AIM 10 nan", 11),
    ("autocollimator1", "AIM 0 30", 13),  # zenith outside the mount range
    ("autocollimator2", "AIM 0 150", 13),
    ("oscillator", "DIV?", 11),
    ("oscillator", "DIV? 3", 12),
    ("oscillator", "DIV? 0", 12),
    ("oscillator", "DIV? one", 11),
    ("oscillator", "DIV? nan", 11),
    ("oscillator", "DIV? 1 2", 11),
    # extra arguments and lenient number forms: refused, no longer half-executed (issue 13)
    ("table", "STOP 2 3 4", 11),
    ("table", "STAT? 1 2", 11),
    ("table", "PPR 1_000", 11),
    ("table", "PPR +10", 11),
    ("table", "POS 2 1e20", 12),
    ("patch_panel", "CLR now", 11),
    ("counter1", "PRESET 1_000", 11),
    ("counter2", "PRESET +1000", 11),
    ("counter3", "MODE X--Y", 11),
    ("counter4", "STBY 1", 11),
    ("autocollimator1", "AIM? 1", 11),
    ("bubble_levels", "LEV? 1", 11),
    ("oscillator", "DIV? +1", 11),
]


@pytest.mark.parametrize(("name", "cmd", "code"), BAD_ARGUMENTS)
def test_malformed_arguments_are_refused_without_effect(station, name, cmd, code):
    d = driver(station, name)
    before = snapshot(station, name)
    raw = exchange(d, cmd.encode() + b"\n")
    assert raw.startswith(f"ERR {code} ".encode())
    with pytest.raises(InstrumentRefused) as e:
        d.query(cmd)
    assert (e.value.code, e.value.instrument) == (code, name)
    assert snapshot(station, name) == before
    assert d.identify() == IDENT[name]


GARBAGE = {
    "non-ascii": [b"\xff\xfe\n"],
    "utf8-in-command": [b"POS 1 10\xc2\xb0\n"],
    "control-chars": [b"\x01\x02\x1b[2J\n"],
    "nul-in-command": [b"*IDN?\x00\n"],
    "tab": [b"POS\t1\t10\n"],
    "long-then-newline": [b"X" * 300, b"\n"],
    "long-in-one-write": [b"X" * 300 + b"\n"],
    "long-in-pieces": [b"X" * 260, b"Y" * 40, b"\n"],
    "long-in-small-pieces": [b"Z" * 100] * 3 + [b"\n"],
}


@pytest.mark.parametrize("garbage", GARBAGE.values(), ids=GARBAGE.keys())
@pytest.mark.parametrize("name", SERIAL_INSTRUMENTS)
def test_garbled_input_gets_one_err_100_and_instrument_recovers(station, rack, name, garbage):
    d = driver(station, name)
    for chunk in garbage:
        assert d.port.write(chunk) == len(chunk)
    reply = d.port.read_until(b"\n")
    assert reply.startswith(b"ERR 100 garbled input")
    # exactly one reply: the next exchange is in step again
    assert d.identify() == IDENT[name]
    assert d.port.in_waiting == 0
    assert_works(station, rack, name)


@pytest.mark.parametrize("name", SERIAL_INSTRUMENTS)
def test_error_queue_returns_errors_in_order_and_clears(station, name):
    d = driver(station, name)
    assert exchange(d, b"SYST:ERR?\n") == b"0 no error\n"
    exchange(d, b"FROB\n")
    exchange(d, b"\xff\n")
    # SYST:ERR? answers "<code> <text>" for the oldest queued error
    assert exchange(d, b"SYST:ERR?\n") == b"10 unknown command 'FROB'\n"
    assert exchange(d, b"SYST:ERR?\n") == b"100 garbled input: not printable ASCII\n"
    assert d.query("SYST:ERR?") == "0 no error"
    assert exchange(d, b"SYST:ERR?\n") == b"0 no error\n"
    exchange(d, b"FROB\n")
    d.clear()
    assert exchange(d, b"SYST:ERR?\n") == b"0 no error\n"


def test_counter_refuses_changes_while_operating_and_bad_wiring(station):
    c, pp = station.counters[2], station.patch_panel
    pp.connect("G1+", 2, "X")
    pp.connect("G2-", 2, "Y")
    pp.connect("OSC1", 2, "Z")
    c.set_mode("measure X-Y")
    with pytest.raises(InstrumentRefused) as e:
        c.operate()  # X-Y of two different gyros is no gating train
    assert e.value.code == 22
    pp.disconnect(2, "Y")
    c.operate()
    with pytest.raises(InstrumentRefused) as e:
        c.set_mode("measure Z")
    assert e.value.code == 23
    with pytest.raises(InstrumentRefused) as e:
        c.set_preset(5)
    assert e.value.code == 23
    assert (c.query("MODE?"), c.query("PRESET?"), c.state()) == ("XY", "1000", "OPER")
    with pytest.raises(DriverError):
        c.set_mode("measure W")  # refused by the driver, never sent


def test_bubble_levels_out_of_range(station, rack):
    station.table.move(1, 10.0)  # rotary axis 10 deg off the vertical
    station.table.wait_still()
    with pytest.raises(InstrumentRefused) as e:
        station.bubble_levels.corrections()
    assert (e.value.code, e.value.text, e.value.instrument) == (40, "OUT OF RANGE", "bubble_levels")
    station.table.move(1, 0.0)
    station.table.wait_still()
    assert_works(station, rack, "bubble_levels")


def test_autocollimator_without_mirror_reports_no_return(station, rack):
    ac = station.autocollimators[1]
    ac.aim(180.0, 90.0)  # looking west: no mirror there
    assert exchange(ac, b"MEAS?\n") == b"ERR 30 NO RETURN\n"
    assert ac.measure() is None
    assert_works(station, rack, "autocollimator1")


@pytest.fixture
def step():
    token = current_step.set("Chart II-6 step 9")
    yield "Chart II-6 step 9"
    current_step.reset(token)


def test_counter_that_never_reaches_preset_times_out_naming_counter_and_step(station, step):
    c, pp = station.counters[3], station.patch_panel
    pp.connect("OSC1", 3, "X")
    pp.connect("TROT", 3, "Z")  # gated by table rotation; the table stands still
    c.set_mode("measure Z")
    c.set_preset(10)
    c.operate()
    t0 = station.clock.now()
    with pytest.raises(LinkTimeout) as e:
        c.read(timeout=2.0)
    assert station.clock.now() - t0 == pytest.approx(2.0, abs=1e-6)  # simulated seconds
    msg = str(e.value)
    assert e.value.instrument == "counter3" and msg.startswith("counter3 (")
    assert e.value.step == step and f"during {step}" in msg
    assert "READ?" in msg
    current_step.set(None)

    c.clear()  # drops the pending READ?
    assert c.identify() == IDENT["counter3"]
    assert (c.state(), c.queued()) == ("OPER", 0)
    # Once the table turns, the same counter gates again: 10 one-degree pulses at 15 deg/s.
    station.table.set_pulses_per_rev(360)
    station.table.rotate(2, 15.0)
    station.table.wait_still()
    c.command("CLR")  # drop the readings of gates that spanned the acceleration
    c.read(timeout=5.0)  # the gate in progress may have opened while the table accelerated
    ticks = c.read(timeout=5.0)
    assert ticks == pytest.approx(10 / 360 * 24 * 1e6, rel=1e-4)


# ----------------------------------------------------------------------------- IEU

DB = load_dbc()
COMMAND_ID = DB.get_message_by_name("IEU_COMMAND").frame_id
ERROR_ID = DB.get_message_by_name("IEU_ERROR").frame_id


def max_period_ticks(cfg) -> int:
    return round(
        cfg.instruments.ieu.max_period_s * cfg.oscillator.nominal_hz / cfg.oscillator.s2_divider
    )


def assert_ieu_samples(st, period: int = 1000) -> None:
    """The IEU still samples: a complete sample whose timer counts the period's S2^T pulses."""
    st.ieu.start(period)
    s = st.ieu.next_sample(timeout=1.0)
    assert s.timer == period
    assert st.ieu.next_sample(timeout=1.0).seq == (s.seq + 1) % 65536
    st.ieu.stop()


BAD_FRAMES = {
    # name: (arbitration id, data, IEU error code)
    "unknown-id": (0x123, bytes(8), 1),
    "sample-id-from-host": (0x101, bytes(8), 1),
    "command-wrong-length": (COMMAND_ID, b"\x03", 2),
    "command-bad-value": (COMMAND_ID, bytes([7]) + bytes(7), 3),
    "start-period-zero": (COMMAND_ID, bytes([1]) + bytes(7), 4),
}


@pytest.mark.parametrize("frame", BAD_FRAMES.values(), ids=BAD_FRAMES.keys())
def test_ieu_refuses_bad_frames(station, rack, frame):
    fid, data, code = frame
    seen = []
    rack.ieu.listeners.append(lambda t, i, d: seen.append((i, d)))
    station.ieu.bus.send(can.Message(arbitration_id=fid, data=data, is_extended_id=False))
    with pytest.raises(InstrumentRefused) as e:
        station.ieu.status()
    assert (e.value.code, e.value.instrument) == (code, "ieu")
    assert f"frame 0x{fid:03x} refused" in str(e.value)
    errors = [DB.decode_message(i, d) for i, d in seen if i == ERROR_ID]
    assert [(e["Code"], e["RefId"]) for e in errors] == [(code, fid)]
    assert station.ieu.status()["ErrorCode"] == code
    assert_ieu_samples(station)


def test_ieu_refuses_too_long_sample_period(station, cfg):
    longest = max_period_ticks(cfg)
    with pytest.raises(InstrumentRefused) as e:
        station.ieu.start(longest + 1)
    assert (e.value.code, e.value.instrument) == (4, "ieu")
    assert station.ieu.status()["State"] == 0
    station.ieu.start(longest)
    assert station.ieu.status()["State"] == 1
    station.ieu.stop()
    assert_ieu_samples(station)


@pytest.mark.parametrize("period", [0, 2**32])
def test_ieu_driver_refuses_periods_the_frame_cannot_carry(station, period):
    with pytest.raises(DriverError) as e:
        station.ieu.start(period)
    assert e.value.instrument == "ieu" and "IEU_COMMAND" in str(e.value)
    assert_ieu_samples(station)


GARBLED_FRAMES = {
    "unknown-id": (0x321, bytes(8)),
    "short-gyro-frame": (0x101, b"\x00\x01"),
    "short-status-frame": (0x081, b"\x01"),
}


@pytest.mark.parametrize("frame", GARBLED_FRAMES.values(), ids=GARBLED_FRAMES.keys())
def test_garbled_frame_at_driver_is_a_driver_error(station, rack, frame):
    fid, data = frame
    rack.ieu.output.append((rack.world.now, fid, data))
    with pytest.raises(DriverError) as e:
        station.ieu.status()
    assert not isinstance(e.value, (InstrumentRefused, LinkTimeout))
    assert e.value.instrument == "ieu" and f"garbled frame id 0x{fid:03x}" in str(e.value)

    # the same in the middle of sampling: one error, then complete samples in sequence
    station.ieu.start(1000)
    rack.ieu.output.append((rack.world.now, fid, data))
    with pytest.raises(DriverError, match="garbled"):
        station.ieu.next_sample(timeout=1.0)
    first = station.ieu.next_sample(timeout=1.0)
    assert first.timer == 1000
    assert station.ieu.next_sample(timeout=1.0).seq == first.seq + 1
