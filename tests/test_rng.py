"""sim.rng.stream: numpy's PCG64 seeded by SeedSequence(seed, spawn_key=names), to the bit,
from its own integer arithmetic (issue 17), and numpy's errors where numpy would raise."""

from __future__ import annotations

import random

import numpy as np
import pytest

from sim.rng import MAX_KEY_WORDS, _key, stream

NAMES = ["esg", "pulses", "clock", "dvm", "cigtf", "", "a name with spaces", "ü"]


def numpy_stream(seed: int, *names: str | int) -> np.random.Generator:
    ss = np.random.SeedSequence(entropy=int(seed), spawn_key=tuple(_key(n) for n in names))
    return np.random.Generator(np.random.PCG64(ss))


def _name(r: random.Random) -> str | int:
    kind = r.randrange(4)
    if kind == 0:
        return r.choice(NAMES)
    if kind == 1:
        return 0
    return r.getrandbits(r.choice([8, 32, 33, 64, 70, 130]))  # one to five words


def _seed(r: random.Random) -> int:
    return r.choice([0, 1, 1970, 2**32 - 1, 2**32, 2**128 - 1, 2**128, r.getrandbits(200),
                     r.getrandbits(r.randint(1, 128))])


def test_same_generator_as_numpy_over_random_seeds_and_names() -> None:
    r = random.Random(20261124)
    for _ in range(3000):
        seed = _seed(r)
        names = tuple(_name(r) for _ in range(r.randint(0, 6)))
        ours, theirs = stream(seed, *names), numpy_stream(seed, *names)
        assert ours.bit_generator.state == theirs.bit_generator.state, (seed, names)
        assert ours.random() == theirs.random()


def test_streams_sharing_a_prefix_stay_apart() -> None:
    # the prefix's pool is cached: every last name must still give numpy's stream
    for last in range(200):
        for seed in (1, 7):
            a, b = stream(seed, "esg", "pulses", 2, last), numpy_stream(seed, "esg", "pulses", 2,
                                                                         last)
            assert a.bit_generator.state == b.bit_generator.state


def test_long_keys_and_refusals_as_numpy() -> None:
    long = tuple(range(1, MAX_KEY_WORDS + 3))  # past the tabulated hash constants
    assert stream(5, *long).bit_generator.state == numpy_stream(5, *long).bit_generator.state
    for seed, names in ((-1, ("x",)), (3, ("x", -2)), (-5, ())):
        with pytest.raises(ValueError, match="non-negative"):
            numpy_stream(seed, *names)
        with pytest.raises(ValueError, match="non-negative"):
            stream(seed, *names)
