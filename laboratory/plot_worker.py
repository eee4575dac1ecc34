"""A run's plots drawn beside the run (issue 17: plots off the critical path).

A child process started when a run starts imports matplotlib (and the plotting modules)
while the simulation runs, then draws the plots it is sent (as soon as their data exist)
while this process goes on; the run waits for them before its end note (only then are
they renamed into place), so the run directory is the same. Where the child cannot be
started, or fails, the same functions draw the same plots here, in this process. A job is
``("module:function", keywords)``; the keyword ``path`` is the file, written atomically.
"""

from __future__ import annotations

import importlib
import os
import pickle
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType
from typing import Any

Job = tuple[str, dict[str, Any]]  # "module:function", its keywords (one of them path)


def temporary(path: Path, pid: int | None = None) -> Path:
    """The temporary a plot of ``path`` is drawn to: ``.<name>.plot-<pid><suffix>``, one
    that station.files.atomic_path's clearing of a record file's stale temporaries
    (``.<stem>.tmp-*``: results.json beside results.png) never matches."""
    return path.with_name(f".{path.name}.plot-{pid or os.getpid()}{path.suffix}")


def _clear_stale(path: Path) -> None:
    for old in path.parent.glob(f".{path.name}.plot-*"):
        old.unlink(missing_ok=True)


def _installed(tmp: Path, path: Path) -> None:
    """``tmp`` synced and renamed over ``path``, the directory synced."""
    from station.files import fsync_dir

    with tmp.open("rb") as f:
        os.fsync(f.fileno())
    os.replace(tmp, path)
    fsync_dir(path.parent)


@contextmanager
def written(path: Path) -> Iterator[Path]:
    """station.files.atomic_path for a plot drawn while the run writes files beside it
    (its temporary is ``temporary(path)``; it clears only its own stale ones)."""
    _clear_stale(path)
    tmp = temporary(path)
    try:
        yield tmp
        if tmp.exists():
            _installed(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _draw(name: str, kw: dict[str, Any]) -> None:
    module, _, function = name.partition(":")
    getattr(importlib.import_module(module), function)(**kw)


def draw_here(jobs: list[Job], raising: bool = False) -> list[str | None]:
    """Draw ``jobs`` in this process, each atomically to its keyword ``path``; per job None,
    or the line of the error that stopped it (``raising``: the error itself)."""
    done: list[str | None] = []
    for name, kw in jobs:
        try:
            with written(Path(kw["path"])) as tmp:
                _draw(name, {**kw, "path": tmp})
            done.append(None)
        except Exception as e:  # noqa: BLE001  # reported; the parent draws it again
            if raising:
                raise
            done.append(f"{name}: {type(e).__name__}: {e}".splitlines()[0])
    return done


class PlotWorker:
    """A child process that draws plot jobs: ``draw`` sends them, ``wait`` returns once
    every plot is written (drawing here what the child did not). ``modules``: those the
    child imports at once, while the run runs (the plotting functions' own).

    The child draws each plot to a temporary beside its file; only ``wait`` renames them
    into place, so a run that stops before it (``close``) leaves no plot it would not have
    left when it drew them itself, at the same point."""

    def __init__(self, *modules: str) -> None:
        self._jobs: list[Job] = []
        self._temps: list[Path] = []
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
        try:
            self._proc: subprocess.Popen[bytes] | None = subprocess.Popen(
                [sys.executable, "-m", "laboratory.plot_worker", *modules],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env)
        except OSError:
            self._proc = None

    def __enter__(self) -> PlotWorker:
        return self

    def __exit__(self, kind: type[BaseException] | None, e: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def draw(self, jobs: list[Job], more: bool = False) -> None:
        """Send ``jobs`` to the child to draw while this process goes on, in the order
        sent; ``more``: other batches follow (a run sends a plot as soon as its data
        exist, and the rest later), else this is the last one."""
        jobs = list(jobs)
        paths = [Path(kw["path"]) for _, kw in jobs]
        for path in paths:
            _clear_stale(path)
        temps = [temporary(path) for path in paths]
        self._jobs += jobs
        self._temps += temps
        p = self._proc
        if p is None or p.stdin is None:
            return
        sent = [(name, {**kw, "path": tmp}) for (name, kw), tmp in zip(jobs, temps, strict=True)]
        try:
            p.stdin.write(pickle.dumps(sent))
            p.stdin.flush()
            if not more:
                p.stdin.close()
        except OSError:  # the child is gone: wait() draws them here
            self._end_child()

    def wait(self) -> None:
        """Every job's plot is in place once this returns."""
        results: list[str | None] = [""] * len(self._jobs)
        p = self._proc
        if p is not None and p.stdout is not None:
            try:
                if p.stdin is not None and not p.stdin.closed:
                    p.stdin.close()  # no more batches: the child answers
                got = pickle.loads(p.stdout.read())
                if isinstance(got, list) and len(got) == len(self._jobs):
                    results = got
            except (OSError, EOFError, pickle.UnpicklingError):
                pass
            self._end_child()
        again = []
        for job, tmp, r in zip(self._jobs, self._temps, results, strict=True):
            if r is None and tmp.exists():
                _installed(tmp, Path(job[1]["path"]))
            else:
                tmp.unlink(missing_ok=True)
                again.append(job)
        self._jobs, self._temps = [], []
        if again:  # as the run drew them before: an error here is the run's
            draw_here(again, raising=True)

    def _end_child(self) -> None:
        p, self._proc = self._proc, None
        if p is None:
            return
        if p.poll() is None:
            p.kill()
        p.wait()
        for f in (p.stdin, p.stdout):
            if f is not None:
                try:
                    f.close()
                except OSError:
                    pass

    def close(self) -> None:
        """End the child if it still runs and remove what it drew but was not installed
        (a run that stopped before its plots)."""
        self._end_child()
        for tmp in self._temps:
            tmp.unlink(missing_ok=True)
        self._jobs, self._temps = [], []


def main() -> None:
    """The child: import matplotlib and the modules named in argv now (while the run
    runs), then draw each batch of jobs read from stdin as it comes and, at its end, write
    every job's outcome to stdout."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401  # the import is the point: done before it is needed

    for module in sys.argv[1:]:
        importlib.import_module(module)

    done: list[str | None] = []
    while True:
        try:
            batch = pickle.load(sys.stdin.buffer)
        except EOFError:
            break
        for name, kw in batch:  # to the parent's temporaries: it renames them
            try:
                _draw(name, kw)
                done.append(None)
            except Exception as e:  # noqa: BLE001  # reported; the parent draws it again
                done.append(f"{name}: {type(e).__name__}: {e}".splitlines()[0])
    if not done:
        return
    sys.stdout.buffer.write(pickle.dumps(done))
    sys.stdout.buffer.flush()


if __name__ == "__main__":
    main()
