"""One BLAS thread for every recorded computation, so a record does not depend on the machine.

OpenBLAS splits a large product or factorisation (the 3K x 3K solve of Charts I-9/I-10)
over its threads, and the sums come out in another order with another thread count: the
level tape of one seed differed in its last bits between a 1-thread and a 2-thread process,
and a resumed run (replayed exactly) refused its own journal when the two processes had
different counts (a Dask import sets OPENBLAS_NUM_THREADS=1 for the processes it starts).
threadpoolctl sets the count of the libraries already loaded (numpy's, whatever the
environment was at its import); OPENBLAS_NUM_THREADS, read by OpenBLAS when it loads, sets
it for those loaded later (scipy.linalg's own build, imported only by the commands that use
it) and for the processes the run starts.
"""

from __future__ import annotations

import os
import sys
from typing import Any

_limit: list[Any] = []  # the process's one controller, kept alive while the process runs
_before_numpy: list[bool] = []  # pinned by the environment before numpy loaded its BLAS


def pin_blas_threads_at_start() -> None:
    """The console script's first step: OPENBLAS_NUM_THREADS=1 before numpy is imported, so
    that OpenBLAS starts with one thread. What the process computes before its run pins the
    count (the plan check) then has the run's bits, no second BLAS thread spins beside the
    plot child, and ``pin_blas_threads`` has nothing left to limit (no threadpoolctl)."""
    if _limit or _before_numpy or "numpy" in sys.modules:
        return  # numpy's BLAS already loaded: pin_blas_threads limits it with threadpoolctl
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    _before_numpy.append(True)


def _numpy_blas_is_openblas() -> bool:
    """Whether numpy was built against OpenBLAS (which reads OPENBLAS_NUM_THREADS when it
    loads); another BLAS (MKL, Accelerate) is limited by threadpoolctl as before."""
    import numpy

    try:
        name = numpy.__config__.CONFIG["Build Dependencies"]["blas"]["name"]
    except (AttributeError, KeyError, TypeError):
        return False
    return "openblas" in str(name).lower()


def pin_blas_threads() -> None:
    """Limit the BLAS libraries of this process to one thread (idempotent, process-wide)."""
    if _limit:
        return
    if (_before_numpy and os.environ.get("OPENBLAS_NUM_THREADS") == "1"
            and _numpy_blas_is_openblas()):
        return  # OpenBLAS started with one thread (pin_blas_threads_at_start)
    os.environ["OPENBLAS_NUM_THREADS"] = "1"  # for the libraries loaded from now on
    import numpy  # noqa: F401 - load numpy's BLAS, so that it is limited too
    from threadpoolctl import threadpool_limits

    _limit.append(threadpool_limits(limits=1, user_api="blas"))
