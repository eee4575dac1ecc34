"""A table axis's angle and rate at one instant (the float path) carry the same bits as the
same instant in an array (numpy's path), over random moves, rate ramps and settles."""

from __future__ import annotations

import numpy as np

from sim.isu.trajectory import Trajectory, plan_move, plan_rate


def test_one_instant_equals_the_array_evaluation_bit_for_bit() -> None:
    rng = np.random.default_rng(20261123)
    for _ in range(10):
        tr = Trajectory(rng.uniform(-1, 1))
        t = 0.0
        for _ in range(5):
            p, v = tr.cut(t)
            if rng.random() < 0.5:
                segs, _ = plan_move(t, p, p + rng.uniform(-3, 3), 0.5, 0.3,
                                    rng.uniform(0, 1e-3), rng.uniform(0.1, 2))
            else:
                segs, _ = plan_rate(t, p, v, rng.uniform(-1, 1), 0.2)
            tr.append(segs)
            t += rng.uniform(1, 30)
        ts = rng.uniform(-1, t + 10, 100)
        p_all, v_all = tr.evaluate(ts)
        for i, x in enumerate(ts):
            p1, v1 = tr.evaluate(np.array([x]))
            assert p1[0] == p_all[i] and v1[0] == v_all[i]
            p2, v2, _ = tr.state(float(x))
            assert p2 == p_all[i] and v2 == v_all[i]



def test_rotation_phase_at_one_instant_equals_the_array_evaluation(rack, station) -> None:
    """The rotary axis's pulse phase (the TROT line a counter's edge search asks one
    instant at a time) against the same instants in one array, bit for bit, through a move,
    a turn at rate and the settle."""
    station.table.move(1, 90.0)
    station.table.rotate(2, -12.0)
    station.table.wait_still()
    station.clock.sleep(40.0)
    table = rack.world.table
    assert table.rotation_output
    ts = np.linspace(0.0, station.clock.now(), 501)
    many = table.rotation_phase(ts)
    assert np.ptp(many) > 1.0  # it turned
    for i, x in enumerate(ts):
        assert float(table.rotation_phase(float(x))) == many[i]


def test_cuts_without_a_plan_between_keep_the_history_held() -> None:
    """Two cuts in a row (a stop asked twice before a new plan, the second later): the axis
    then follows the segment holding the first cut, by both paths, as a history of those
    segments alone. Before, the second cut read start times the first had dropped
    (IndexError)."""
    rng = np.random.default_rng(20261207)
    for _ in range(20):
        tr = Trajectory(rng.uniform(-1, 1))
        segs, done = plan_move(1.0, tr.state(1.0)[0], rng.uniform(-3, 3), 0.5, 0.3,
                               rng.uniform(0, 1e-3), rng.uniform(0.1, 2))
        tr.append(segs)
        t1 = rng.uniform(1.0, done)
        t2 = rng.uniform(t1, done + 5.0)
        tr.cut(t1)
        tr.cut(t2)
        kept = Trajectory()
        kept.append(list(tr.segments))
        assert [s.ts for s in tr.segments] == [s.ts for s in kept.segments]
        assert tr.segments[-1].ts <= t1
        ts = rng.uniform(0.0, done + 10.0, 50)
        for x in ts:
            assert tr.state(float(x)) == kept.state(float(x))
        assert np.array_equal(tr.evaluate(ts)[0], kept.evaluate(ts)[0])
