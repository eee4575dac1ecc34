"""Faster paths of issue 17 held bit for bit to the computation each replaced, on random
inputs: a table axis at a few instants, an alignment's raw samples as rows, CSV cells, and
the pier tilt a turning gyro sees over a gate (Chart II-7Q's speed sigmas)."""

from __future__ import annotations

import math

import numpy as np

from laboratory.export import csv_cell
from procedures.isu.alignment.sampling import RAW_COLUMNS, RawSamples
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.count_sigma import tilt_seen_turning_arcsec
from sim.isu.environment import Environment
from sim.isu.trajectory import Trajectory, plan_move, plan_rate


def _random_trajectory(rng: np.random.Generator) -> tuple[Trajectory, float]:
    tr = Trajectory(rng.uniform(-1, 1))
    t = 0.0
    for _ in range(6):
        p, v = tr.cut(t)
        if rng.random() < 0.5:
            segs, _ = plan_move(t, p, p + rng.uniform(-3, 3), 0.5, 0.3, rng.uniform(0, 1e-3),
                                rng.uniform(0.1, 2))
        else:
            segs, _ = plan_rate(t, p, v, rng.uniform(-1, 1), 0.2)
        tr.append(segs)
        t += rng.uniform(1, 30)
    return tr, t


def test_a_few_instants_carry_the_bits_of_the_same_instants_in_a_long_array() -> None:
    rng = np.random.default_rng(20261128)
    for _ in range(20):
        tr, t_end = _random_trajectory(rng)
        ts = rng.uniform(-1, t_end + 10, 200)
        p_all, v_all = tr.evaluate(ts)
        for n in (2, 3, 7, 16, 17):
            i = int(rng.integers(0, ts.size - n))
            p, v = tr.evaluate(ts[i:i + n])
            assert p.shape == v.shape == (n,)
            assert np.array_equal(p, p_all[i:i + n]) and np.array_equal(v, v_all[i:i + n])
        p2, v2 = tr.evaluate(ts[:6].reshape(2, 3))  # the shape asked for comes back
        assert p2.shape == (2, 3) and np.array_equal(p2.ravel(), p_all[:6])
        assert np.array_equal(v2.ravel(), v_all[:6])


def test_raw_samples_rows_are_the_samples_element_by_element() -> None:
    rng = np.random.default_rng(7)
    n = 57
    raw = RawSamples(np.arange(100, 100 + n), np.cumsum(rng.uniform(0.09, 0.11, n)),
                     rng.integers(0, 2**20, n), rng.integers(0, 16, n),
                     rng.integers(-5000, 5000, (n, 3)), rng.integers(0, 2**24, (n, 6)))
    rows = raw.rows()
    assert len(rows) == n
    for i, row in enumerate(rows):
        want = (int(raw.seq[i]), float(raw.t[i]), int(raw.timer[i]), int(raw.flags[i]),
                *(int(x) for x in raw.gyro[i]), *(int(x) for x in raw.strings[i]))
        assert list(row) == list(RAW_COLUMNS)
        assert tuple(row.values()) == want
        assert [type(x) for x in row.values()] == [type(x) for x in want]


def test_csv_cells_are_written_as_before() -> None:
    """Each kind of cell as the export wrote it before the lookup by exact type: floats by
    repr (exact round trip), ints and strings as they are, None empty, booleans in JSON's
    words, containers as sorted JSON; a numpy float as the float it is (it was written as
    "np.float64(2.5)", which no reader takes for a number)."""
    rng = np.random.default_rng(11)
    cells: list[tuple[object, str]] = [
        (None, ""), (True, "true"), (False, "false"), (0, "0"), (-0.0, "-0.0"),
        (math.inf, "inf"), (-math.inf, "-inf"), (math.nan, "nan"), (10**30, "1" + "0" * 30),
        ("a,b", "a,b"), ("", ""), ([1, 2.5], "[1, 2.5]"), ((1,), "[1]"),
        ({"b": 1, "a": [None]}, '{"a": [null], "b": 1}'),
        (np.float64(2.5), "2.5"), (np.int64(3), "3")]
    cells += [(x, repr(x)) for x in (float(v) for v in rng.normal(0, 1e6, 50))]
    cells += [(x, str(x)) for x in (int(v) for v in rng.integers(-2**40, 2**40, 50))]
    for v, want in cells:
        assert csv_cell(v) == want, v
        if isinstance(v, float) and not math.isnan(v):
            assert float(csv_cell(v)) == v


def _tilt_seen_turning_full(noise: NoiseSpec, gate_s: float, rate_deg_s: float,
                            steps: int = 240) -> float:
    t = np.linspace(0.0, gate_s, steps + 1)
    ee, _, _ = noise.tilt_covariance(np.subtract.outer(t, t))
    cov = np.diff(np.diff(ee, axis=0), axis=1)
    w = math.radians(rate_deg_s) * 0.5 * (t[1:] + t[:-1])
    c, s = np.cos(w), np.sin(w)
    var = 0.5 * float(c @ cov @ c + s @ cov @ s)
    return math.sqrt(max(var, 0.0)) * 180.0 / math.pi * 3600.0


def test_tilt_seen_by_a_turning_axis_from_the_mirrored_triangle() -> None:
    rng = np.random.default_rng(3)
    for _ in range(40):
        noise = NoiseSpec.model_validate({
            "wobble_period_s": float(rng.uniform(20, 200)),
            "wobble_coherence_s": float(rng.uniform(50, 5000)),
            "wobble_amplitude_arcsec": float(rng.uniform(0, 3)),
            "tilt_wander_tau_s": float(rng.uniform(100, 1e5)),
            "tilt_wander_sigma_arcsec": float(rng.uniform(0, 3)),
        })
        gate, rate = float(rng.uniform(1, 400)), float(rng.uniform(0.1, 20))
        steps = int(rng.integers(20, 260))
        full = _tilt_seen_turning_full(noise, gate, rate, steps)
        assert tilt_seen_turning_arcsec(noise, gate, rate, steps) == full
        # asked again on an equal noise model (another object): the held value, the same
        hits = tilt_seen_turning_arcsec.cache_info().hits
        again = NoiseSpec.model_validate(noise.model_dump())
        assert tilt_seen_turning_arcsec(again, gate, rate, steps) == full
        assert tilt_seen_turning_arcsec.cache_info().hits == hits + 1
        # another lab's noise with the same gate and rate is computed for itself
        other = NoiseSpec.model_validate({**noise.model_dump(), "wobble_amplitude_arcsec":
                                          noise.wobble_amplitude_arcsec + 0.5})
        assert (tilt_seen_turning_arcsec(other, gate, rate, steps)
                == _tilt_seen_turning_full(other, gate, rate, steps) != full)


def test_one_instant_of_the_noise_processes_carries_the_bits_of_an_array() -> None:
    """A pier wander (Gauss-Markov), a random walk and the floor vibration at one time, in
    the scalar paths, against the same times in the array paths: labs drawn at random
    (knot spacing, sigma, tau, band, tones), times before 0, on knots and far out."""
    from sim.noise import gauss_markov, random_walk
    from station.config.isu import load_config

    base = load_config().world_params().environment

    rng = np.random.default_rng(20261207)
    for _ in range(30):
        seed = int(rng.integers(0, 2**31))
        h = float(rng.uniform(0.05, 120.0))
        gm = gauss_markov(h, rng.uniform(1e-7, 1e-3), rng.uniform(0.5 * h, 1e5), seed, "gm")
        rw = random_walk(h, rng.uniform(1e-12, 1e-4), seed, "rw")
        ts = np.concatenate((rng.uniform(-10.0, 5e5, 40), h * rng.integers(0, 5000, 5),
                             [0.0, -1.0]))
        want_i, want_v = gm.integral(ts), rw.value(ts)
        for i, t in enumerate(ts):
            for x in (float(t), np.float64(t)):
                got_i, got_v = gm.integral(x), rw.value(x)
                assert type(got_i) is float and type(got_v) is float
                assert got_i == want_i[i] and got_v == want_v[i]
        p = base.model_copy(update={"vibration": base.vibration.model_copy(update={
            "rms_micro_g": float(rng.uniform(0.1, 500.0)), "tones": int(rng.integers(1, 64)),
            "band_hz": tuple(sorted(rng.uniform(0.05, 200.0, 2).tolist()))})})
        env = Environment(p, seed)
        for t in ts:
            one = env.vibration_velocity(t)
            each = np.stack([m.integral(np.atleast_1d(t)) for m in env.vibration], axis=-1)
            assert one.shape == (1, 3) and np.array_equal(one, each)


def _tilt_one_by_one(env: Environment, t: float) -> tuple[np.ndarray, np.ndarray]:
    """The pier tilt and rate at one time as tilt_and_rate computed it before (issue 17):
    each wander and wobble process on a one-element array."""
    ta = np.atleast_1d(np.asarray(t, dtype=float))
    eps, rate = env._diurnal(ta)
    env._add_wander_and_wobble(ta, eps, rate)
    return eps, rate


def test_the_pier_tilt_at_one_instant_carries_the_bits_it_had() -> None:
    """Environment.tilt_and_rate at one time (the wander in Python floats, the two wobble
    axes stacked) against each process asked on its own: piers drawn at random."""
    from station.config.isu import load_config

    base = load_config().world_params().environment
    rng = np.random.default_rng(7)
    for _ in range(20):
        pier = base.pier_tilt.model_copy(update={
            "wander_sigma_arcsec": float(rng.uniform(0.01, 5.0)),
            "wander_tau_s": float(rng.uniform(100.0, 1e5)),
            "diurnal_pp_arcsec": float(rng.uniform(0.0, 10.0))})
        wobble = base.wobble.model_copy(update={
            "amplitude_arcsec": float(rng.uniform(0.0, 2.0)),
            "period_s": float(rng.uniform(1.0, 60.0))})
        env = Environment(base.model_copy(update={"pier_tilt": pier, "wobble": wobble}),
                          int(rng.integers(0, 2**31)))
        for t in np.concatenate((rng.uniform(-5.0, 9e4, 30), [0.0, 60.0, 120.0])):
            eps, rate = env.tilt_and_rate(t)
            want_eps, want_rate = _tilt_one_by_one(env, t)
            assert eps.shape == rate.shape == (1, 3)
            assert np.array_equal(eps, want_eps) and np.array_equal(rate, want_rate)


def test_a_line_keeps_its_phases_only_while_the_world_stands() -> None:
    """A pulse line's kept phases are the phase functions' own bits, and a table command
    (the world's next revision) drops them: asked again, every line answers what its phase
    function gives under the new plan (laboratories drawn at random)."""
    from sim.isu.world import World
    from tests.random_labs import random_lab

    rng = np.random.default_rng(20261207)
    for lab in rng.integers(0, 10_000, 3):
        world = World(random_lab(int(lab)).world_params(), int(lab))
        lines = [world.line(n) for n in ("G1", "G2+", "A1S1", "A3S2", "TROT")]
        ts = [float(x) for x in rng.uniform(0.0, 400.0, 12)]
        before = {}
        for t in ts + ts[::-1]:  # each instant asked twice: the second from the kept ones
            for ln in lines:
                v = ln.phase(t)
                assert v == ln._phase(t)
                before[ln.name, t] = v
        world.table.rotate(2, float(rng.uniform(0.05, 0.3)), 0.0)  # rad/s from t = 0
        world.changed()
        moved = 0
        for t in ts:
            for ln in lines:
                v = ln.phase(t)
                assert v == ln._phase(t)
                moved += v != before[ln.name, t]
        assert moved > len(ts)  # the plan changed what the lines see


def test_a_trajectory_keeps_its_arrays_as_built_afresh() -> None:
    """Cuts and appends convert only the new segments: after each, the arrays are those
    built from every segment held, the starts are in order, and breakpoints and state read
    them as a scan of every start would (random command sequences, some appended without a
    cut, some replacing a segment at the same start, some appending nothing)."""
    rng = np.random.default_rng(20261207)
    for _ in range(30):
        tr = Trajectory(rng.uniform(-1, 1))
        t = 0.0
        for _ in range(int(rng.integers(5, 40))):
            t += float(rng.choice([0.0, rng.uniform(0.0, 30.0)]))
            if rng.random() < 0.8:
                p, v = tr.cut(t)
            else:
                p, v = tr.state(t)[:2]
            if rng.random() < 0.5:
                segs, _ = plan_move(t, p, p + rng.uniform(-3, 3), 0.5, 0.3,
                                    rng.uniform(0, 1e-3), rng.uniform(0.1, 2))
            else:
                segs, _ = plan_rate(t, p, v, rng.uniform(-1, 1), 0.2)
            tr.append(segs if rng.random() < 0.95 else [])
            starts = [s.ts for s in tr.segments]
            assert starts == sorted(set(starts))  # in order; one at a start replaced
            fresh = Trajectory(0.0)
            fresh.segments = list(tr.segments)
            fresh._arrays()
            assert np.array_equal(tr._ts, fresh._ts) and np.array_equal(tr._kind, fresh._kind)
            assert np.array_equal(tr._par, fresh._par) and tr._ts_list == fresh._ts_list
            for t0, t1 in rng.uniform(-1.0, t + 40.0, (5, 2)):
                assert tr.breakpoints(t0, t1) == [float(x) for x in tr._ts if t0 < x < t1]


def test_medians_are_numpys() -> None:
    """procedures.medians.median against numpy.median: odd and even lengths, flattened and
    along each axis, sliding windows (the IEU's outlier screen), ties and NaN."""
    from procedures.medians import median

    rng = np.random.default_rng(20261208)
    for _ in range(200):
        shape = tuple(int(n) for n in rng.integers(1, 7, int(rng.integers(1, 4))))
        x = rng.normal(0.0, 10.0 ** rng.uniform(-6, 6), shape)
        if rng.random() < 0.3:
            x = np.round(x, 1)  # ties
        if rng.random() < 0.2:
            x.flat[int(rng.integers(0, x.size))] = np.nan
        for axis in (None, *range(x.ndim), -1):
            want = np.median(x, axis=axis)
            got = median(x, axis=axis)
            assert np.array_equal(got, want, equal_nan=True)
            assert np.shape(got) == np.shape(want)
        if x.ndim >= 1 and x.shape[0] >= 3:
            win = np.lib.stride_tricks.sliding_window_view(x, 3, axis=0)
            assert np.array_equal(median(win, axis=-1), np.median(win, axis=-1),
                                  equal_nan=True)
    assert median([2.0, 1.0, 4.0, 3.0]) == 2.5 and median([5.0]) == 5.0


def test_a_tables_frames_at_one_instant_carry_the_bits_of_an_array() -> None:
    """FourAxisTable.frames at one instant (sim.frames' one-instant gimbal and rotation)
    against the array path at that instant: every matrix, the tilt rate, the angles and
    rates, on random labs with the axes moving, turning, settling or still, and rotation
    vectors down to the small-angle branch."""
    from sim.frames import transform_of_rotated, transform_of_rotated_at
    from sim.isu.world import World
    from tests.random_labs import random_lab

    rng = np.random.default_rng(20261209)
    for lab in rng.integers(0, 10_000, 4):
        world = World(random_lab(int(lab)).world_params(), int(lab))
        tb = world.table
        lo, hi = (math.radians(x) for x in tb.p.trunnion_range_deg)
        tb.move(1, float(rng.uniform(lo, hi)), 0.0)
        tb.move(3, float(rng.uniform(-0.3, 0.3)), 0.0)
        tb.move(4, float(rng.uniform(-3.0, 3.0)), 0.0)
        tb.rotate(2, float(rng.uniform(0.05, 0.3)), 0.0)
        for t in rng.uniform(0.0, 120.0, 15):
            one = tb.frames(float(t))
            many = tb._frames_of(np.array([t]))
            for key in ("t_io", "t_or", "t_rt", "t_tf", "t_fe", "eps_rate"):
                assert one[key].shape == (1, *many[key].shape[1:])
                assert np.array_equal(one[key][0], many[key][0]), key
            for k in (1, 2, 3, 4):
                assert one["angles"][k][0] == many["angles"][k][0]
                assert one["rates"][k][0] == many["rates"][k][0]
    for v in rng.normal(0.0, 1.0, (200, 3)) * 10.0 ** rng.uniform(-12, 0, (200, 1)):
        assert np.array_equal(transform_of_rotated_at(v), transform_of_rotated(v[None])[0])


def test_the_attitude_alone_is_the_kinematics_attitude_bit_for_bit() -> None:
    """World.attitude (an autocollimator's reading) makes T^BE without the rate and force:
    the same matrix, bit for bit, as kinematics gives at that instant, with the table
    still, turning and settling (laboratories drawn at random)."""
    from sim.isu.world import World
    from tests.random_labs import random_lab

    rng = np.random.default_rng(1207)
    for lab in rng.integers(0, 10_000, 3):
        world = World(random_lab(int(lab)).world_params(), int(lab))
        world.table.move(3, float(rng.uniform(-1.0, 1.0)), 0.0)  # rad: a slew, then a settle
        world.table.rotate(2, float(rng.uniform(0.05, 0.3)), 60.0)
        world.changed()
        for t in rng.uniform(0.0, 400.0, 20):
            assert np.array_equal(world.attitude(float(t)), world.kinematics(float(t))[0][0])


def test_functionals_fourier_transforms_carry_the_bits_of_add_at() -> None:
    """kernels.fourier adds each functional's atoms one after another (``_add_rows``), as
    np.add.at does: the same bits on random functionals (points, gates, empty ones, many
    atoms each) and frequency sets, signed zeros included."""
    import math

    from procedures.isu.calibration import kernels
    from procedures.isu.calibration.kernels import Functional, fourier

    rng = np.random.default_rng(20261207)
    for _ in range(60):
        fs = []
        for _ in range(int(rng.integers(1, 40))):
            atoms = []
            for _ in range(int(rng.integers(0, 9))):
                a = float(rng.uniform(-100.0, 4e4))
                b = a if rng.random() < 0.3 else a + float(rng.uniform(0.0, 600.0))
                atoms.append((float(rng.normal() * 10.0 ** rng.uniform(-6, 6)), a, b))
            fs.append(Functional(tuple(atoms)))
        freqs = rng.uniform(-0.05, 0.05, int(rng.integers(1, 400)))
        freqs[0] = 0.0
        owner, w, a, b = kernels._flatten(fs)
        want = np.zeros((len(fs), freqs.size), dtype=complex)
        if owner.size:
            ph = (np.exp(2j * math.pi * np.outer(0.5 * (a + b), freqs))
                  * np.sinc(np.outer(b - a, freqs)))
            np.add.at(want, owner, w[:, None] * ph)
        got = fourier(fs, freqs)
        assert got.view(np.uint64).tobytes() == want.view(np.uint64).tobytes()
