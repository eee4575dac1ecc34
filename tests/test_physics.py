"""The instruments return what the physics says: counts against independent integrations
of the Chart IV-1 / IV-2 models, analytic counters against a pulse-by-pulse reference, the
IEU against a counter, autocollimators against the true mirror normals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import simpson

from sim import units
from sim.isu import reference
from station.config.isu import load_config
from station.racks.isu import SimulatedRack, open_isu_drivers


@pytest.fixture
def lab():
    cfg = load_config(seed=11)
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    yield rack, st
    st.close()
    rack.close()


def _position(st, angles):
    for ax, deg in zip((1, 2, 3, 4), angles, strict=True):
        st.table.move(ax, deg)
    st.table.wait_still()


def _gyro_angle_model(world, k: int, t: np.ndarray) -> np.ndarray:
    """Chart IV-2 written out in lab units and integrated with Simpson's rule (rad)."""
    g = world.isu.gyros[k]
    p = g.p
    t_be, _, _ = world.kinematics(t)
    # Angular rate from the attitude history: [w_BE x] = -dT/dt T^T, plus Earth rate.
    dt = t[1] - t[0]
    dT = np.gradient(t_be, dt, axis=0)
    wx = -np.einsum("nij,nkj->nik", dT, t_be)
    w_rel = np.stack([wx[:, 2, 1], wx[:, 0, 2], wx[:, 1, 0]], axis=-1)
    w_e = world.site.omega_e * np.array(
        [math.cos(world.site.colatitude), 0.0, math.sin(world.site.colatitude)]
    )
    w = np.einsum("nij,j->ni", t_be, w_e) + w_rel
    a = np.einsum("nij,j->ni", t_be, np.array([world.site.g, 0.0, 0.0])) / units.G0  # in g
    c = units.DEG / units.HOUR
    wg_lab = (w @ g.G) / c  # deg/hr
    ws_lab = (w @ g.S) / c
    ag, ao, as_ = a @ g.G, a @ g.O, a @ g.S
    drift_lab = (
        p.R_deg_hr
        + p.B_I_deg_hr_g * ag
        + p.B_O_deg_hr_g * ao
        + p.B_S_deg_hr_g * as_
        + p.C_II_deg_hr_g2 * ag**2
        + p.C_SS_deg_hr_g2 * as_**2
        + p.C_IS_deg_hr_g2 * ag * as_
        + p.C_OS_deg_hr_g2 * ao * as_
        + p.C_IO_deg_hr_g2 * ag * ao
        + p.Q_II_hr_deg * wg_lab**2
        + p.Q_IS_hr_deg * wg_lab * ws_lab
    )
    rate = (w @ g.G) + drift_lab * c
    return np.array([simpson(rate[: i + 1], x=t[: i + 1]) for i in (0, len(t) - 1)])


def test_gyro_counter_measure_z_matches_model(lab):
    """Position 7 style (phi1 = 0, phi2 = 90): a 600 s "measure Z" gate on each gyro."""
    rack, st = lab
    w = rack.world
    _position(st, (0.0, 90.0, 0.0, 0.0))
    st.clock.sleep(5.0)
    pp = st.patch_panel
    for k in (1, 2, 3):
        c = k + 1
        pp.connect(f"G{k}+", c, "X")
        pp.connect(f"G{k}-", c, "Y")
        pp.connect("OSC1", c, "Z")
        st.counters[c].set_mode("measure Z")
        st.counters[c].set_preset(600_000_000)  # 600 s of S1^T = 1 us
    t_oper = {}
    for k in (1, 2, 3):
        t_oper[k] = st.clock.now()
        st.counters[k + 1].operate()
    counts = [st.counters[k + 1].read(timeout=700.0) for k in (1, 2, 3)]
    osc = w.line("OSC1")
    for k in (1, 2, 3):
        t_open = osc.edge_after(t_oper[k], 1)
        t_close = osc.edge_after(t_open, 600_000_000)
        assert 599.999 < t_close - t_open < 600.001
        g = w.isu.gyros[k - 1]
        line = w.line(f"G{k}")
        s0, s1 = line.last_sample(t_open), line.last_sample(t_close)
        grid = np.linspace(s0, s1, 12001)
        ang = _gyro_angle_model(w, k - 1, grid)
        _, w0, _ = w.kinematics(s0)
        _, w1, _ = w.kinematics(s1)
        j = g.J * float((w1[0] - w0[0]) @ g.O)
        noise = float(g.noise_angle(s1) - g.noise_angle(s0))
        ph0 = w.gyro_phase(k - 1, s0)
        expected = math.floor(ph0 + (ang[1] - ang[0] + j + noise) / g.dphi) - math.floor(ph0)
        assert abs(counts[k - 1] - expected) <= 1, (k, counts[k - 1], expected)
        # and the noise-free model alone agrees within the model's noise (4 sigma) + 1 count
        arw = g.p.arw_deg_rt_hr * units.DEG / 60 * math.sqrt(600.0)
        drift = g.p.drift_sigma_deg_hr * units.DEG_PER_HR * 600.0
        tol = 4 * math.hypot(arw, drift) / g.dphi + 1
        assert abs(counts[k - 1] - (ang[1] - ang[0] + j) / g.dphi) <= tol


def test_string_counter_measure_xy_is_edge_to_edge_interval(lab):
    """ "measure X-Y" on accelerometer strings: clock ticks between the gate's leading edges."""
    rack, st = lab
    w = rack.world
    _position(st, (0.0, 90.0, 0.0, 0.0))
    n = 1_200_000  # ten minutes at the 20 kHz basic frequency (II-6.2)
    for c, line in ((1, "A1S1"), (2, "A1S2"), (5, "A3S1")):
        st.patch_panel.connect(line, c, "X")
        st.patch_panel.connect("OSC1", c, "Z")
        st.counters[c].set_mode("measure X-Y")
        st.counters[c].set_preset(n)
    t_oper = {}
    for c in (1, 2, 5):
        t_oper[c] = st.clock.now()  # OPER takes effect when the line arrives
        st.counters[c].operate()
    for c, line in ((1, "A1S1"), (2, "A1S2"), (5, "A3S1")):
        ticks_read = st.counters[c].read(timeout=700.0)
        x = w.line(line)
        t_open = x.edge_after(t_oper[c], 1)
        t_close = x.edge_after(t_open, n)
        assert math.floor(x.phase(t_open)) == math.floor(x.phase(t_open + 1e-9))
        assert x.count(t_open, t_close) == n
        osc = w.line("OSC1")
        assert ticks_read == osc.count(t_open, t_close)
        # against the model: f = N / T within the string's noise
        k, s = int(line[1]) - 1, int(line[3])
        acc = w.isu.accels[k]
        a = w.kinematics(0.5 * (t_open + t_close))[2][0]
        u = a @ acc.A / units.G0
        diff = acc.D1 * (u + acc.D0 + acc.D2 * u**2 + acc.D3 * u**3)
        f_model = acc.f0 + acc.kappa * u * u + (-0.5 if s == 1 else 0.5) * diff
        f_meas = n / (ticks_read * w.oscillator.s1_nominal)
        sigma = 0.5 * acc.D1 * acc.p.noise_micro_g_rt_hz * 1e-6 / math.sqrt(600.0)
        # tilt wander and wobble over the gate move u by ~1e-6 g on a vertical axis
        assert abs(f_meas - f_model) < 4 * sigma + acc.D1 * 2e-5


@pytest.mark.parametrize("line", ["A2S1", "A2S2"])
def test_analytic_counter_equals_pulse_by_pulse_reference(lab, line):
    rack, st = lab
    w = rack.world
    _position(st, (0.0, 90.0, 0.0, 0.0))
    c = 3
    n = 500
    st.patch_panel.connect(line, c, "X")
    st.patch_panel.connect("OSC1", c, "Z")
    st.counters[c].set_mode("measure X-Y")
    st.counters[c].set_preset(n)
    t_cmd = st.clock.now()
    # the reference fires one simpy event per string pulse over the same span
    k, s = int(line[1]) - 1, int(line[3])
    tg, ph = reference.string_phase_grid(w, k, s, t_cmd, t_cmd + 0.06, 1e-6)
    edges = reference.crossings(tg, ph)
    fired: list[float] = []
    reference.fire_pulses(w, edges, fired)
    st.counters[c].operate()
    ticks_read = st.counters[c].read(timeout=1.0)
    st.counters[c].standby()
    st.clock.sleep(0.1)
    fired = np.array(fired)
    assert len(fired) == len(edges) > n + 1
    x = w.line(line)
    t_open = x.edge_after(t_cmd, 1)
    t_close = x.edge_after(t_open, n)
    # same edge times (to a hundredth of a clock tick) and the same count
    assert abs(t_open - fired[0]) < 1e-8
    assert abs(t_close - fired[n]) < 1e-8
    # (the two edge-time paths agree to < 1e-8 s, so compare counts half a tick past the edge)
    assert x.count(t_cmd, t_close) == int(np.sum(fired <= t_close + 5e-7)) == n + 1
    assert ticks_read == w.line("OSC1").count(fired[0], fired[n])


def test_ieu_frames_sum_to_counter_count(lab):
    _, st = lab
    _position(st, (0.0, 90.0, 0.0, 0.0))
    period, k_samples = 1000, 50  # 0.1 s samples for 5 s
    pp = st.patch_panel
    pp.connect("G3+", 4, "X")
    pp.connect("G3-", 4, "Y")
    pp.connect("A2S1", 5, "X")
    for c in (4, 5):
        pp.connect("OSC2", c, "Z")
        st.counters[c].set_mode("measure Z")
        st.counters[c].set_preset(period * k_samples)
    st.ieu.start(period)  # both gates open on the same S2^T edge
    st.counters[4].operate()
    st.counters[5].operate()
    samples = [st.ieu.next_sample() for _ in range(k_samples)]
    st.ieu.stop()
    assert [s.seq for s in samples] == list(range(k_samples))
    assert all(s.timer == period for s in samples)
    assert sum(s.gyro[2] for s in samples) == st.counters[4].read(timeout=1.0)
    assert sum(s.accel[2] for s in samples) == st.counters[5].read(timeout=1.0)


def test_autocollimator_reads_true_mirror_normal(lab):
    rack, st = lab
    w = rack.world
    _position(st, (0.0, 90.0, 90.0, 0.0))  # survey position: B1 east, B2 north
    from instruments.isu.autocollimator import angles

    ac_noise = units.arcsec(rack.cfg.instruments.autocollimator.noise_arcsec)
    for i in (1, 2):
        m = w.mirror_normals(st.clock.now())[i - 1]
        az, zen = (math.degrees(x) for x in angles(m))
        st.autocollimators[i].aim(az + 0.2, zen - 0.1)
        reads, truth = [], []
        for _ in range(40):
            reads.append(st.autocollimators[i].measure())
            # the pier moves (wobble, tilt): compare with the normal at the reading's time
            truth.append(angles(w.mirror_normals(st.clock.now())[i - 1]))
        reads, truth = np.radians(np.array(reads)), np.array(truth)
        d_az = (reads[:, 0] - truth[:, 0]) * np.sin(truth[:, 1])
        d_zen = reads[:, 1] - truth[:, 1]
        for d in (d_az, d_zen):
            assert abs(d.mean()) < 4 * ac_noise / math.sqrt(40)
            assert 0.6 * ac_noise < d.std() < 1.5 * ac_noise
    # outside the field of view there is no return
    st.autocollimators[1].aim(az + 2.0, zen)
    assert st.autocollimators[1].measure() is None


def test_kinematics_angular_rate_matches_attitude_history(lab):
    """During a slew, w_B - T^BE w_E equals the rate read off dT^BE/dt."""
    rack, st = lab
    w = rack.world
    st.table.move(3, 40.0)
    t = st.clock.now() + np.linspace(0.5, 2.5, 2001)
    t_be, w_b, _ = w.kinematics(t)
    dT = np.gradient(t_be, t[1] - t[0], axis=0)
    wx = -np.einsum("nij,nkj->nik", dT, t_be)
    w_fd = np.stack([wx[:, 2, 1], wx[:, 0, 2], wx[:, 1, 0]], axis=-1)
    w_model = w_b - np.einsum("nij,j->ni", t_be, w.site.earth_rate_e)
    assert np.abs(w_model[5:-5] - w_fd[5:-5]).max() < 1e-6 * np.abs(w_model).max() + 1e-9


def test_same_seed_same_readings_other_seed_differs():
    def run(seed):
        cfg = load_config(seed=seed)
        with SimulatedRack(cfg) as rack:
            st = open_isu_drivers(cfg, rack)
            _position(st, (0.0, 90.0, 0.0, 0.0))
            st.patch_panel.connect("G1+", 2, "X")
            st.patch_panel.connect("G1-", 2, "Y")
            st.patch_panel.connect("OSC1", 2, "Z")
            st.counters[2].set_preset(60_000_000)
            st.counters[2].operate()
            vals = [st.counters[2].read(timeout=100.0) for _ in range(3)]
            st.close()
            return vals, st.clock.now()

    a, b, c = run(5), run(5), run(6)
    assert a == b
    assert a != c


def test_falling_gate_counts_exactly_preset_turns(lab):
    """A table turning backwards gates a counter on falling phase: N turns, not N - 1."""
    rack, st = lab
    st.table.move(1, 90.0)
    st.table.rotate(2, -12.0)
    st.table.wait_still()
    pp = st.patch_panel
    pp.connect("OSC1", 1, "X")
    pp.connect("TROT", 1, "Z")
    st.counters[1].set_mode("measure Z")
    st.counters[1].set_preset(3)
    st.counters[1].operate()
    ticks = st.counters[1].read(timeout=200.0)
    # three turns at 12 deg/s take 90 s (the resolver's cyclic error cancels over whole turns)
    assert abs(ticks * rack.world.oscillator.s1_nominal - 90.0) < 1e-4
    line = rack.world.line("TROT")
    t0 = line.edge_after(st.clock.now(), 1)
    t1 = line.edge_after(t0, 2)
    assert line.count(t0, t1) == -2
