"""ESG laboratory (report 004): the serial protocols of the data processor, dividing head,
turntable, theodolite and gyro console, and their drivers.

Silent processor (decided here, documented in docs/protocols.md): a processor that does not
acknowledge ``GO`` makes ``lines()`` raise ``LinkTimeout`` naming the processor; one that
falls silent in the middle of a stream makes ``lines()`` return the lines it got followed
by ``BadLine("", "line lost: ...")`` entries, after which the driver has halted the stream
and emptied its input so that the next command works.
"""

from __future__ import annotations

import math

import pytest

from sim.timebase import ticks
from station.drivers.esg import BadLine, DataLine, LineChecker
from station.errors import DriverError, InstrumentRefused, LinkTimeout
from station.racks.esg import LATENCY_S, EsgRack, open_esg_drivers

SEED = 11
IDENT = {
    "processor": "ESG-LAB,DATA-PROCESSOR,0,1.0",
    "head": "ESG-LAB,DIVIDING-HEAD,0,1.0",
    "turntable": "ESG-LAB,TURNTABLE-TILT,0,1.0",
    "theodolite": "ESG-LAB,THEODOLITE,0,1.0",
    "console": "ESG-LAB,GYRO-CONSOLE,0,1.0",
}


@pytest.fixture
def rack():
    with EsgRack(SEED) as r:
        yield r


@pytest.fixture
def st(rack):
    s = open_esg_drivers(rack)
    yield s
    s.close()


def exchange(drv, line: bytes) -> bytes:
    """Write raw bytes and return the next reply line as it came off the wire."""
    drv.port.write(line)
    return drv.port.read_until(b"\n")


def spinning(st, rack) -> None:
    """Rotor at speed (the console's spin-up, if the world does not start spinning)."""
    if rack.world.console_status()["spin_rps"] < 0.99 * rack.world.p.rotor.spin_rps:
        st.console.spin_up()
        st.clock.sleep(rack.world.p.rotor.spinup_s + 60.0)
    assert st.console.speed() == pytest.approx(rack.world.p.rotor.spin_rps, rel=0.01)


# ----------------------------------------------------------------------------- round trips


def test_identities_and_common_commands(st):
    for name, ident in IDENT.items():
        d = getattr(st, name)
        assert d.identify() == ident
        assert d.query("SYST:ERR?") == "0 no error"
        d.clear()


def test_processor_settings_round_trip(st, rack):
    p = st.processor
    s0 = p.settings()
    assert s0["pickoffs"] == (2, 3)
    assert (s0["revolutions"], s0["run"]) == (10, 0)
    assert s0["threshold_v"] == 1.5 and s0["min_width_us"] == 20.0
    assert s0["logic_delay_us"] == pytest.approx(rack.processor.settings.logic_delay_us, rel=1e-5)
    p.select(1, 3)
    p.revolutions(4)
    p.run_number(1234567)
    p.threshold(2.25)
    p.discriminator(12)
    p.delay(350)
    assert p.settings() == {"pickoffs": (1, 3), "revolutions": 4, "run": 1234567,
                            "threshold_v": 2.25, "min_width_us": 12.0, "logic_delay_us": 350.0}
    assert exchange(p, b"SET?\n") == b"1 3 4 1234567 2.25 12 350\n"
    ps = rack.processor.settings
    assert (ps.threshold_v, ps.min_width_us, ps.logic_delay_us) == (2.25, 12.0, 350.0)
    st.clock.sleep(100.0)
    p.time_zero()
    # the clock restarted when TZERO arrived, one reply latency ago
    assert rack.processor.clock_hours() == pytest.approx(LATENCY_S / 3600, abs=1e-12)
    p.halt()  # nothing streaming: still OK


def test_head_round_trip(st, rack):
    h = st.head
    assert h.status() == "HOLD" and h.reading() == 0.0
    h.set(45)
    assert h.status() == "MOVING"
    h.wait_hold()
    assert h.reading() == 45.0
    assert exchange(h, b"SPIN?\n") == b"45.00000\n"
    h.step(-50.5)
    h.wait_hold()
    assert exchange(h, b"SPIN?\n") == b"354.50000\n"
    h.set(-10.000001)  # the driver takes angles modulo 360, to the scale's 1e-5 deg
    h.wait_hold()
    assert h.reading() == 350.0
    assert exchange(h, b"SPIN 12.3456789\n") == b"OK\n"  # the scale rounds to 5 decimals
    h.wait_hold()
    assert exchange(h, b"SPIN?\n") == b"12.34568\n"
    assert rack.world.head_reading_deg() == pytest.approx(12.34568, abs=1e-9)


def test_turntable_round_trip(st):
    t = st.turntable
    assert t.status() == "HOLD"
    t.azimuth(-90.0)  # modulo 360 in the driver
    assert t.status() == "MOVING"
    t.wait_hold()
    t.tilt(30.12346)
    t.wait_hold()
    assert t.readings() == (270.0, 30.1235)  # 4 decimals
    assert exchange(t, b"AZ?\n") == b"270.0000\n"
    assert exchange(t, b"TILT?\n") == b"30.1235\n"
    t.lock()
    assert t.status() == "LOCKED"
    t.tilt(-12.5)  # tilt still moves with the azimuth locked
    assert t.status() == "MOVING"
    t.wait_hold()
    assert t.status() == "LOCKED"
    t.unlock()
    assert t.status() == "HOLD"
    t.azimuth(10.0)
    t.wait_hold()
    assert t.readings() == (10.0, -12.5)


def test_theodolite_round_trip(st, rack):
    x, y = st.theodolite.read()
    raw = exchange(st.theodolite, b"READ?\n").decode()
    assert len(raw.split()) == 2 and all("." in v for v in raw.split())
    true_x, true_y = rack.world.theodolite_arcsec()
    # the residual coning of mirror 1 is at most 3 arcsec; the readings scatter about it
    assert abs(x) < 10 and abs(y) < 10
    assert abs(x - true_x) < 5 and abs(y - true_y) < 5


def test_console_round_trip(st, rack):
    c = st.console
    s = c.status()
    assert set(s) == {"suspended", "spin_rps", "damping", "pressure_torr"}
    raw = exchange(c, b"STAT?\n").decode()
    f = raw.split()
    assert f[0::2] == ["SUSP", "SPIN", "DAMP", "VAC"] and "E" in f[7]
    c.damping(True)
    assert c.status()["damping"] is True
    c.damping(False)
    assert c.status()["damping"] is False
    c.spin_off()
    st.clock.sleep(10.0)
    assert c.speed() == c.status()["spin_rps"]


def test_console_spin_up_rises_to_250(st, rack):
    c = st.console
    s = c.status()
    assert s["suspended"] and s["spin_rps"] == 0.0  # the rotor starts at rest
    c.spin_up()
    speeds = []
    for _ in range(10):
        st.clock.sleep(rack.world.p.rotor.spinup_s / 10)
        speeds.append(c.status()["spin_rps"])
    assert all(b > a for a, b in zip(speeds, speeds[1:], strict=False)), speeds
    assert speeds[0] == pytest.approx(25.0, abs=0.5)
    assert speeds[-1] == pytest.approx(250.0, abs=0.01)
    assert exchange(c, b"STAT?\n").startswith(b"SUSP 1 SPIN 250.00 DAMP 0 VAC 5.0E-07")
    assert c.speed() == pytest.approx(250.0, abs=0.01)


# ----------------------------------------------------------------------------- refusals


@pytest.mark.parametrize("name", IDENT)
def test_unknown_command_names_instrument(st, name):
    d = getattr(st, name)
    assert exchange(d, b"FROB 1\n") == b"ERR 10 unknown command 'FROB'\n"
    with pytest.raises(InstrumentRefused) as e:
        d.query("WIBBLE?")
    assert (e.value.code, e.value.instrument) == (10, name)
    assert str(e.value).startswith(f"{name} (sim://{name}")
    assert d.identify() == IDENT[name]


BAD_ARGUMENTS = [
    # (instrument, command, code, what the message names)
    ("processor", "SEL 2", 11, "usage: SEL <a> <b>"),
    ("processor", "SEL 2 2", 12, "pickoffs must be distinct, got 2 2"),
    ("processor", "SEL 0 2", 12, "pickoff a 0 outside [1, 3]"),
    ("processor", "SEL 1 4", 12, "pickoff b 4 outside [1, 3]"),
    ("processor", "SEL one 2", 11, "pickoff a must be an integer"),
    ("processor", "REV 3", 12, "revolutions must be one of 1, 2, 4, 8, 10, got 3"),
    ("processor", "REV 0", 12, "revolutions 0 outside [1, 10]"),
    ("processor", "REV 2.5", 11, "revolutions must be an integer"),
    ("processor", "RUN -1", 12, "run number -1 outside [0, 9999999]"),
    ("processor", "RUN 10000000", 12, "run number 10000000 outside"),
    ("processor", "THR 0.05", 12, "threshold 0.05 outside [0.1, 5]"),
    ("processor", "THR nan", 11, "threshold must be finite"),
    ("processor", "THR", 11, "usage: THR <volts>"),
    ("processor", "DISC 30", 12, "discriminator width 30 outside [2, 24]"),
    ("processor", "DISC 1", 12, "discriminator width 1 outside [2, 24]"),
    ("processor", "DELAY 10", 12, "logic delay 10 outside [20, 2000]"),
    ("processor", "DELAY 2500", 12, "logic delay 2500 outside [20, 2000]"),
    ("processor", "DELAY x", 11, "logic delay must be a number, got 'x'"),
    ("processor", "TZERO 5", 11, "usage: TZERO"),
    ("processor", "GO 0", 12, "line count 0 outside [1, 1000000]"),
    ("processor", "GO 1 2", 11, "usage: GO [<k>]"),
    ("processor", "GO 2.5", 11, "line count must be an integer"),
    ("processor", "HALT now", 11, "usage: HALT"),
    ("processor", "SET? 1", 11, "usage: SET?"),
    ("head", "SPIN 360", 12, "spindle angle 360 outside [0, 360)"),
    ("head", "SPIN -1", 12, "spindle angle -1 outside [0, 360)"),
    ("head", "SPIN inf", 11, "spindle angle must be finite"),
    ("head", "SPIN", 11, "usage: SPIN <deg>"),
    ("head", "STEP 400", 12, "spindle step 400 outside [-360, 360]"),
    ("head", "STEP ten", 11, "spindle step must be a number, got 'ten'"),
    ("head", "SPIN? 1", 11, "usage: SPIN?"),
    ("head", "SHIM 200 0", 12, "shim x 200 outside [-120, 120]"),
    ("head", "SHIM 1", 11, "usage: SHIM <x> <y>"),
    ("turntable", "AZ 360", 12, "azimuth 360 outside [0, 360)"),
    ("turntable", "AZ", 11, "usage: AZ <deg>"),
    ("turntable", "TILT 91", 12, "tilt 91 outside [-90, 90]"),
    ("turntable", "TILT -90.5", 12, "tilt -90.5 outside [-90, 90]"),
    ("turntable", "TILT nan", 11, "tilt must be finite"),
    ("turntable", "LOCK 1", 11, "usage: LOCK"),
    ("turntable", "AZ? 2", 11, "usage: AZ?"),
    ("theodolite", "READ? 1", 11, "usage: READ?"),
    ("console", "SPIN", 11, "usage: SPIN UP|OFF"),
    ("console", "SPIN DOWN", 12, "SPIN takes UP or OFF, got 'DOWN'"),
    ("console", "DAMP 1", 12, "DAMP takes ON or OFF, got '1'"),
    ("console", "DAMP ON OFF", 11, "usage: DAMP ON|OFF"),
    ("console", "SPEED? x", 11, "usage: SPEED?"),
    ("console", "XLATE 4 0 0", 12, "pickoff 4 outside [1, 3]"),
    ("console", "XLATE 1 0 -121", 12, "translation b -121 outside [-120, 120]"),
]


def state(st, name: str):
    d = getattr(st, name)
    if name == "processor":
        return d.settings()
    if name == "head":
        return (d.reading(), d.status())
    if name == "turntable":
        return (d.readings(), d.status())
    if name == "console":
        s = d.status()
        return (s["suspended"], s["damping"])
    return ()


@pytest.mark.parametrize(("name", "cmd", "code", "text"), BAD_ARGUMENTS)
def test_bad_arguments_are_refused_naming_what_is_wrong(st, name, cmd, code, text):
    d = getattr(st, name)
    before = state(st, name)
    raw = exchange(d, cmd.encode() + b"\n").decode()
    assert raw.startswith(f"ERR {code} ")
    assert text in raw
    with pytest.raises(InstrumentRefused) as e:
        d.query(cmd)
    assert (e.value.code, e.value.instrument) == (code, name)
    assert text in str(e.value)
    assert state(st, name) == before
    assert d.query("SYST:ERR?").startswith(f"{code} ")


def test_moves_refused_while_moving_and_azimuth_while_locked(st):
    h, t = st.head, st.turntable
    h.set(90.0)
    for cmd in ("SPIN 10", "STEP 1"):
        with pytest.raises(InstrumentRefused) as e:
            h.command(cmd)
        assert (e.value.code, e.value.instrument) == (16, "head")
        assert "busy" in e.value.text
    h.wait_hold()
    assert h.reading() == 90.0

    t.tilt(20.0)
    for cmd in ("AZ 10", "TILT 5", "LOCK"):
        with pytest.raises(InstrumentRefused) as e:
            t.command(cmd)
        assert (e.value.code, e.value.instrument) == (16, "turntable")
    t.wait_hold()
    t.lock()
    with pytest.raises(InstrumentRefused) as e:
        t.azimuth(45.0)
    assert (e.value.code, e.value.instrument) == (18, "turntable")
    assert "locked" in e.value.text
    assert t.readings() == (0.0, 20.0) and t.status() == "LOCKED"


# ----------------------------------------------------------------------------- head truth


def test_head_spin_45_holds_the_true_spindle_angle(st, rack):
    st.head.set(45)
    st.head.wait_hold()
    assert exchange(st.head, b"SPIN?\n") == b"45.00000\n"
    true_deg = math.degrees(rack.world.mount.angles(rack.world.now)[2])  # (A, E, gamma)
    assert abs(true_deg - 45.0) * 3600 < 2.0


def test_wait_hold_times_out_naming_the_instrument(st, rack):
    st.head.set(180.0)
    with pytest.raises(LinkTimeout) as e:
        st.head.wait_hold(timeout=0.5, poll=0.1)
    assert e.value.instrument == "head" and "MOVING" in str(e.value)
    st.turntable.tilt(60.0)
    with pytest.raises(LinkTimeout) as e:
        st.turntable.wait_hold(timeout=0.2, poll=0.1)
    assert e.value.instrument == "turntable"


# ----------------------------------------------------------------------------- data lines


def cr_sigma(rack, cr: float, rev: int = 10) -> float:
    """Line-to-line count-ratio scatter from the processor's timing noise.

    sim.esg.processor: every edge the HIT fires on carries 80 ns rms Gaussian jitter (its
    fixed channel delay cancels in both counts; the 10 ns clock quantisation and the 1e-9
    clock offset are negligible or cancel). C1 sums REV start-stop pairs, 2 REV jittered
    edges; the period sum spans two line-1 edges; both are over REV / rps seconds, so
    sigma(CR) = jitter sqrt(2 REV + 2 CR^2) rps / REV (about 9e-6 at 250 rps, REV 10; the
    module quotes about 1e-5 at 244 rps).
    """
    j = rack.world.p.signal.jitter_ns * 1e-9
    rps = rack.world.console_status()["spin_rps"]
    return j * math.sqrt(2 * rev + 2 * cr * cr) * rps / rev


def check_truth(rack, lines: list[DataLine], pickoffs) -> None:
    """Every count ratio within 5 sigma of the truth at its line time, rms about sigma."""
    t0 = rack.processor.t_zero
    res = []
    for ln in lines:
        t = (t0 + ticks(ln.time_hr * 3600.0)) / 1e9
        for p in pickoffs:
            cr = ln.count_ratio(p)
            sigma = cr_sigma(rack, cr)
            res.append((cr - rack.world.true_count_ratio(p, t)) / sigma)
            assert abs(res[-1]) < 5.0, (ln, p, res[-1])
    rms = math.sqrt(sum(r * r for r in res) / len(res))
    assert 0.5 < rms < 1.6, rms


def test_stream_of_k_lines_times_and_count_ratios(st, rack):
    spinning(st, rack)
    p = st.processor
    p.time_zero()
    p.run_number(42)
    got = p.lines(12)
    assert len(got) == 12 and all(isinstance(x, DataLine) for x in got), got
    units = [round(x.time_hr * 1e5) for x in got]
    assert all(u % 20 == 0 for u in units)
    assert [b - a for a, b in zip(units, units[1:], strict=False)] == [20] * 11
    assert all(x.run == 42 and x.c1[0] == 0 for x in got)
    for x in got:
        f = x.raw.split(" ")
        assert len(f) == 6 and all(len(v) == 7 and v.isdigit() for v in f)
        assert f[1] == "0000000" and f[4] == "0000042"
    check_truth(rack, got, (2, 3))
    with pytest.raises(ValueError, match="pickoff 1 has no count"):
        got[0].count_ratio(1)
    # the stream is over: the next command is answered at once
    assert p.port.in_waiting == 0
    assert p.settings()["run"] == 42


def test_first_line_waits_for_rev_revolutions_and_comes_after_the_ok(st, rack):
    spinning(st, rack)
    p = st.processor
    p.revolutions(1)
    p.select(2, 1)
    grid = ticks(0.72)
    acq = ticks(2 / rack.world.console_status()["spin_rps"])  # REV + 1 line-1 edges, 8 ms
    # GO sent `lead` before a grid point of the processor clock; the OK leaves 10 ms later
    for lead in (0.3, 0.02, 0.009, 0.005, 0.0):
        left = (grid - (rack.env.now - rack.processor.t_zero) % grid) % grid
        st.clock.sleep(((left - ticks(lead)) % grid) / 1e9)
        p.port.write(b"GO 2\n")
        t_cmd = rack.env.now
        n_next = -((rack.processor.t_zero - t_cmd) // grid)
        want = n_next if ticks(lead) >= acq else n_next + 1
        assert p.port.read_until(b"\n") == b"OK\n"  # first, even when the line is due
        first = p.port.read_until(b"\n")
        assert int(first[:7]) == 20 * want, lead
        assert p.port.read_until(b"\n")[:7] == b"%07d" % (20 * (want + 1))


def test_continuous_stream_interleaves_replies_until_halt(st, rack):
    spinning(st, rack)
    p = st.processor
    assert exchange(p, b"GO\n") == b"OK\n"
    st.clock.sleep(3.0)
    assert p.port.in_waiting >= 3 * 48
    # settings are refused while streaming; queries are answered between the lines
    with pytest.raises(InstrumentRefused) as e:
        p.revolutions(2)
    assert e.value.code == 16 and "HALT" in e.value.text
    with pytest.raises(InstrumentRefused):
        p.command("GO 3")
    assert p.settings()["revolutions"] == 10  # the driver skips the data lines before it
    p.halt()
    st.clock.sleep(5.0)
    assert p.port.in_waiting == 0
    got = p.lines(2)
    assert all(isinstance(x, DataLine) for x in got)


def test_corrupted_lines_become_badlines_and_clean_ones_match_truth(st, rack):
    spinning(st, rack)
    rack.processor.corrupt_every = 2
    p = st.processor
    p.select(3, 2)
    got = p.lines(20)
    bad, good = got[1::2], got[0::2]
    assert all(isinstance(x, BadLine) for x in bad), bad
    assert all(isinstance(x, DataLine) for x in good), good
    non_digit = [x for x in bad if "has a non-digit" in x.reason]
    digit = [x for x in bad if x.reason.startswith("C1 >= period")]
    assert len(non_digit) == len(digit) == 5  # the two kinds alternate
    for x in bad:
        assert x.raw and x.reason
        assert not hasattr(x, "c1") and not hasattr(x, "count_ratio")  # nothing to parse
    check_truth(rack, good, (2, 3))
    # the corrupted lines were good before corruption: same seed, no corruption
    with EsgRack(SEED) as r2:
        s2 = open_esg_drivers(r2)
        try:
            spinning(s2, r2)
            s2.processor.select(3, 2)  # the same exchanges at the same simulated times
            clean = s2.processor.lines(20)
        finally:
            s2.close()
    assert [x.raw for x in clean[0::2]] == [x.raw for x in good]
    for x, c in zip(bad, clean[1::2], strict=True):
        assert isinstance(c, DataLine)
        # one character replaced (a non-ASCII byte shows as \xNN), in the first two places
        # of a selected C1 field or of the period sum
        diff = [i for i, (u, v) in enumerate(zip(x.raw, c.raw, strict=False)) if u != v]
        assert diff and diff[0] in (16, 17, 24, 25, 40, 41), (x.raw, c.raw)
        if len(x.raw) == len(c.raw):
            assert len(diff) == 1
        else:
            assert x.raw[diff[0]:diff[0] + 2] == "\\x" and len(x.raw) == len(c.raw) + 3


def test_silent_processor_go_times_out_naming_processor(st, rack):
    p = st.processor
    p.settings()
    rack.processor.silent = True
    t0 = st.clock.now()
    with pytest.raises(LinkTimeout) as e:
        p.lines(3)
    assert e.value.instrument == "processor" and "GO 3" in str(e.value)
    assert st.clock.now() - t0 == pytest.approx(p.timeout, abs=0.05)
    rack.processor.silent = False
    assert p.identify() == IDENT["processor"]
    assert p.settings()["pickoffs"] == (2, 3)


def test_processor_silent_mid_stream_loses_lines_and_driver_resyncs(st, rack):
    spinning(st, rack)
    p = st.processor
    p.settings()

    def mute():
        yield rack.env.timeout(ticks(2.5))
        rack.processor.silent = True
        yield rack.env.timeout(ticks(8.0))
        rack.processor.silent = False

    rack.env.process(mute())
    got = p.lines(10)
    n = sum(isinstance(x, DataLine) for x in got)
    assert 2 <= n <= 4
    assert all(isinstance(x, DataLine) for x in got[:n])
    assert got[n:] == [BadLine("", f"line lost: stream ended after {n} of 10 lines")] * (10 - n)
    assert not rack.processor.streaming
    st.clock.sleep(10.0)
    assert p.port.in_waiting == 0
    assert p.settings()["revolutions"] == 10
    assert all(isinstance(x, DataLine) for x in p.lines(3))


def test_stopped_rotor_and_off_pattern_pickoff(st, rack):
    p = st.processor
    # at rest (the start state) counter A sees no line-1 edges: no period sum, no line
    got = p.lines(2)
    assert all(isinstance(x, BadLine) and x.reason.startswith("period sum is 0") for x in got)
    spinning(st, rack)
    # the spin axis starts on c1, so pickoff 1 looks along it, off the pattern: its C1 is
    # a legitimate 0 that the line checks accept and count_ratio refuses
    p.select(2, 1)
    got = p.lines(3)
    assert all(isinstance(x, DataLine) and x.c1[0] == 0 and x.c1[1] > 0 for x in got), got
    assert math.isnan(rack.world.true_count_ratio(1, rack.world.now))
    with pytest.raises(ValueError, match="pickoff 1 has no count"):
        got[0].count_ratio(1)
    assert 0.4 < got[0].count_ratio(2) < 0.6


def test_halt_ends_a_counted_stream_early(st, rack):
    spinning(st, rack)
    p = st.processor
    assert exchange(p, b"GO 100\n") == b"OK\n"
    first = [p.port.read_until(b"\n") for _ in range(2)]
    assert all(len(x) == 48 for x in first)
    p.halt()
    assert not rack.processor.streaming
    st.clock.sleep(5.0)
    assert p.port.in_waiting == 0
    assert p.settings()["revolutions"] == 10


@pytest.mark.parametrize("name", IDENT)
def test_garbled_input_gets_err_100_and_instrument_recovers(st, name):
    d = getattr(st, name)
    assert exchange(d, b"\xff\xfeSPIN 1\n") == b"ERR 100 garbled input: not printable ASCII\n"
    assert exchange(d, b"X" * 300 + b"\n") == b"ERR 100 garbled input: line too long\n"
    assert d.identify() == IDENT[name]
    assert d.port.in_waiting == 0


# ----------------------------------------------------------------------------- line checks


def lines_of(*raw: bytes, selected=(2, 3), run=0) -> list:
    c = LineChecker(set(selected), run)
    return [c.check(r) for r in raw]


GOOD = [b"0000100 0000000 2800000 1200000 0000000 4000000\n",
        b"0000120 0000000 2800004 1200001 0000000 4000002\n"]


@pytest.mark.parametrize(("second", "reason"), [
    (b"0000120 0000000 28?0004 1200001 0000000 4000002\n", "field 3 has a non-digit"),
    (b"0000120 0000000 2800004 1200001 0000000 40\xb30002\n", "field 6 has a non-digit"),
    (b"\xff\xfe\n", "expected 6 fields of 7 digits, got 1 fields"),
    (b"0000120 0000000 2800004 1200001 0000000\n", "expected 6 fields of 7 digits, got 5"),
    (b"0000120  0000000 2800004 1200001 0000000 4000002\n", "got 7 fields"),
    (b"0000120 0000000 280004 1200001 0000000 4000002\n", "field 3 has 6 digits, not 7"),
    (b"0000140 0000000 2800004 1200001 0000000 4000002\n", "time not 0.0002 h after the "
                                                          "previous line"),
    (b"0000130 0000000 2800004 1200001 0000000 4000002\n", "not a multiple of 0.0002 h"),
    (b"0000120 0000000 2800004 1200001 0000001 4000002\n", "run number 0000001, expected"),
    (b"0000120 0000005 2800004 1200001 0000000 4000002\n", "pickoff 1 is not selected"),
    (b"0000120 0000000 4800004 1200001 0000000 4000002\n", "C1 >= period (pickoff 2"),
    (b"0000120 0000000 2800004 1200001 0000000 2000002\n", "C1 >= period (pickoff 2"),
    (b"0000120 0000000 0000000 0000000 0000000 0000000\n", "period sum is 0"),
])
def test_line_checks_give_specific_reasons(second, reason):
    a, b = lines_of(GOOD[0], second)
    assert isinstance(a, DataLine)
    assert isinstance(b, BadLine) and reason in b.reason, b
    assert b.raw == second.rstrip(b"\n").decode("ascii", errors="backslashreplace")


def test_line_checks_accept_good_lines_and_zero_for_an_off_pattern_pickoff():
    a, b = lines_of(*GOOD)
    assert (a.time_hr, a.c1, a.run, a.period_sum) == (0.001, (0, 2800000, 1200000), 0, 4000000)
    assert b.count_ratio(2) == 2800004 / 4000002
    (z,) = lines_of(b"0000100 0000000 0000000 1200000 0000000 4000000\n")
    assert isinstance(z, DataLine) and z.count_ratio(3) == 0.3
    with pytest.raises(ValueError, match="pickoff 2 has no count"):
        z.count_ratio(2)
    with pytest.raises(ValueError):
        z.count_ratio(4)
    # the time reference skips a bad line: the line after it is still checked against it
    x, y, w = lines_of(GOOD[0], b"0000120 0000000 2?00000 1200000 0000000 4000000\n",
                       b"0000140 0000000 2800000 1200000 0000000 4000000\n")
    assert isinstance(y, BadLine) and isinstance(w, DataLine)
    # times wrap at 10^7 units
    u, v = lines_of(b"9999980 0000000 2800000 1200000 0000000 4000000\n",
                    b"0000000 0000000 2800000 1200000 0000000 4000000\n")
    assert isinstance(v, DataLine)


def test_lines_needs_a_positive_count(st):
    for k in (0, -3, 2.5):
        with pytest.raises(DriverError) as e:
            st.processor.lines(k)
        assert e.value.instrument == "processor" and "k >= 1" in str(e.value)
    assert st.processor.identify() == IDENT["processor"]  # nothing was sent
