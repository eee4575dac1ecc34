"""A record does not depend on the machine's BLAS threads (station/numerics.py).

OpenBLAS sums a large product in another order with another thread count; before the runs
pinned it to one thread, the level tape (Charts I-9/I-10) of one seed differed in its last
bits between a 1-thread and a 2-thread process, and a run killed in one process refused to
resume in the other (the replay differed from its journal at Chart I-7 step 4)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

VOLATILE = {"wall", "run_uid"}


def _align(out: Path, threads: int, seed: int) -> list[dict]:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": str(threads), "OMP_NUM_THREADS": str(threads)}
    subprocess.run([sys.executable, "-m", "laboratory.cli", "align", "--method", "level",
                    "--quiet", "--seed", str(seed), "--out", str(out)],
                   env=env, check=True, capture_output=True)
    return [{k: v for k, v in json.loads(line).items() if k not in VOLATILE}
            for line in (out / "journal.jsonl").read_text().splitlines()]


@pytest.mark.parametrize("seed", [7])
def test_level_alignment_is_the_same_with_one_or_two_blas_threads(tmp_path, seed):
    one = _align(tmp_path / "one", 1, seed)
    two = _align(tmp_path / "two", 2, seed)
    assert len(one) == len(two) > 300
    for a, b in zip(one, two, strict=True):
        assert a == b, (a.get("chart"), a.get("step"))


_PROBE = """
import sys
{first}
from station.numerics import pin_blas_threads, pin_blas_threads_at_start
pin_blas_threads_at_start()
import numpy
pin_blas_threads()
used = 'threadpoolctl' in sys.modules
from threadpoolctl import threadpool_info
print(used, [d['num_threads'] for d in threadpool_info() if d['user_api'] == 'blas'])
"""


@pytest.mark.parametrize(("first", "pinned_by"), [("", "environment"),
                                                  ("import numpy", "threadpoolctl")])
def test_blas_has_one_thread_however_the_process_started(first, pinned_by):
    """The console script pins OpenBLAS by the environment before numpy loads it (no second
    thread, no threadpoolctl); a process that loaded numpy first is limited by threadpoolctl
    when its run starts. Either way every BLAS library has one thread."""
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS",
                                                            "OMP_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", _PROBE.format(first=first)], env=env,
                         check=True, capture_output=True, text=True).stdout.split(maxsplit=1)
    assert out[0] == str(pinned_by == "threadpoolctl")
    threads = json.loads(out[1])
    assert threads and all(n == 1 for n in threads)
