"""Seeded random streams: every random process draws from a stream named after it.

A stream depends only on (run seed, names), never on the order in which processes are
queried, so the same seed and config give the same world whatever the procedure does.

Each stream is numpy's PCG64 seeded by ``SeedSequence(seed, spawn_key=names)``. A run
opens thousands of them (one per DVM reading, per ESG data line), and numpy's SeedSequence
costs 30 us of Python-level setup per stream (issue 17). ``_SeedState`` computes the same
seed words in plain integers: the pool after the run seed's four words is the same for
every stream of a run and is computed once, the pool after every name but the last is
cached (streams differ mostly in their last name, a time or an index), and only the last
name's words are mixed per stream.
The words are numpy's to the bit (tests/test_rng.py holds them against SeedSequence).
"""

from __future__ import annotations

import zlib
from functools import cache, lru_cache
from typing import Any, cast

import numpy as np
from numpy.random.bit_generator import ISeedSequence

MASK32 = 0xFFFFFFFF
POOL = 4  # SeedSequence's default pool of 32-bit words
PCG64_WORDS = 4  # the 64-bit seed words PCG64 asks of its seed sequence
# SeedSequence's hash constants (numpy/random/bit_generator.pyx, after O'Neill's seed_seq)
INIT_A, MULT_A = 0x43B0D7E5, 0x931E8875
INIT_B, MULT_B = 0x8B51F9DD, 0x58F38DED
MIX_L, MIX_R = 0xCA01F9DD, 0x4973F715
Pool = tuple[int, int, int, int]


def _key(name: str | int) -> int:
    if isinstance(name, int):
        return name
    return zlib.crc32(name.encode("utf-8"))


def _words(n: int) -> list[int]:
    """``n`` as 32-bit words, lowest first (one word for 0), as SeedSequence splits it."""
    if n < 0:
        raise ValueError("expected non-negative integer")
    out = [0] if n == 0 else []
    while n > 0:
        out.append(n & MASK32)
        n >>= 32
    return out


def _hashes(init: int, mult: int, n: int) -> tuple[int, ...]:
    """The hash constants init * mult**k (mod 2**32), k = 0..n: the k-th hashmix of a
    SeedSequence xors with the k-th and multiplies by the next."""
    out = [init]
    for _ in range(n):
        out.append((out[-1] * mult) & MASK32)
    return tuple(out)


RUN_HASHES = POOL + POOL * (POOL - 1)  # hashmixes of the run seed's stage
MAX_KEY_WORDS = 64  # longer keys (none in the station) take numpy's own path
_A = _hashes(INIT_A, MULT_A, RUN_HASHES + POOL * MAX_KEY_WORDS)
_B = _hashes(INIT_B, MULT_B, 2 * PCG64_WORDS)  # generate_state's, two per 64-bit word


def _hashmix(value: int, k: int) -> int:
    """SeedSequence's k-th hashmix of ``value``: xor the k-th hash constant, multiply by
    the next, fold the high half in (``_mixed`` writes it out per pool word)."""
    v = ((value ^ _A[k]) * _A[k + 1]) & MASK32
    return v ^ (v >> 16)


def _mix(x: int, y: int) -> int:
    r = (MIX_L * x - MIX_R * y) & MASK32
    return r ^ (r >> 16)


def _mixed(pool: Pool, words: tuple[int, ...] | list[int], k: int) -> Pool:
    """``pool`` with key ``words`` mixed in, each into every pool word (SeedSequence's
    third stage), starting at hashmix ``k``; the loop over the pool written out."""
    m0, m1, m2, m3 = pool
    a = _A
    for w in words:
        v = ((w ^ a[k]) * a[k + 1]) & MASK32
        r = (MIX_L * m0 - MIX_R * (v ^ (v >> 16))) & MASK32
        m0 = r ^ (r >> 16)
        v = ((w ^ a[k + 1]) * a[k + 2]) & MASK32
        r = (MIX_L * m1 - MIX_R * (v ^ (v >> 16))) & MASK32
        m1 = r ^ (r >> 16)
        v = ((w ^ a[k + 2]) * a[k + 3]) & MASK32
        r = (MIX_L * m2 - MIX_R * (v ^ (v >> 16))) & MASK32
        m2 = r ^ (r >> 16)
        v = ((w ^ a[k + 3]) * a[k + 4]) & MASK32
        r = (MIX_L * m3 - MIX_R * (v ^ (v >> 16))) & MASK32
        m3 = r ^ (r >> 16)
        k += POOL
    return m0, m1, m2, m3


@cache
def _run_pool(seed: int) -> Pool:
    """The pool once a run seed of at most four words is mixed in (padded to four with
    zeros, as SeedSequence pads it when a spawn key follows); RUN_HASHES hashmixes."""
    words = _words(seed)
    pool = [_hashmix(w, k) for k, w in enumerate(words + [0] * (POOL - len(words)))]
    k = POOL
    for src in range(POOL):
        for dst in range(POOL):
            if src != dst:
                pool[dst] = _mix(pool[dst], _hashmix(pool[src], k))
                k += 1
    return pool[0], pool[1], pool[2], pool[3]


@lru_cache(maxsize=1024)
def _prefix(seed: int, names: tuple[str | int, ...]) -> tuple[Pool, int] | None:
    """The pool after the run seed and every name but a stream's last (streams differ
    mostly in their last name, a time or an index), and the key words so far; None past
    MAX_KEY_WORDS."""
    words = [w for n in names for w in _words(_key(n))]
    if len(words) > MAX_KEY_WORDS:
        return None
    return _mixed(_run_pool(seed), words, RUN_HASHES), len(words)


class _SeedState(ISeedSequence):
    """``SeedSequence(seed, spawn_key=keys).generate_state(4, np.uint64)``, PCG64's seed,
    from the mixed pool: the same words, from plain integers."""

    def __init__(self, pool: Pool) -> None:
        out = []
        for i, m in enumerate(pool + pool):
            d = ((m ^ _B[i]) * _B[i + 1]) & MASK32
            out.append(d ^ (d >> 16))
        self.state = np.array([out[0] | out[1] << 32, out[2] | out[3] << 32,
                               out[4] | out[5] << 32, out[6] | out[7] << 32], np.uint64)

    def generate_state(self, n_words: int, dtype: Any = np.uint32) -> np.ndarray:
        if n_words != PCG64_WORDS or np.dtype(dtype) != np.dtype(np.uint64):
            raise ValueError("_SeedState gives PCG64's seed only: 4 words of 64 bits")
        return self.state.copy()


def stream(seed: int, *names: str | int) -> np.random.Generator:
    """A generator for the process identified by ``names`` under run ``seed``."""
    seed = int(seed)
    before = _prefix(seed, names[:-1]) if names and 0 <= seed < 1 << (32 * POOL) else None
    if before is not None:
        last = _words(_key(names[-1]))
        if before[1] + len(last) <= MAX_KEY_WORDS:
            pool = _mixed(before[0], last, RUN_HASHES + POOL * before[1])
            seeded = cast(np.random.SeedSequence, _SeedState(pool))  # an ISeedSequence,
            return np.random.Generator(np.random.PCG64(seeded))  # which PCG64 takes
    ss = np.random.SeedSequence(entropy=seed, spawn_key=tuple(_key(n) for n in names))
    return np.random.Generator(np.random.PCG64(ss))
