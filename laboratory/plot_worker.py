"""A run's plots drawn beside the run (issue 17: plots off the critical path).

A child process started when a run starts imports matplotlib (and the plotting modules)
while the simulation runs, then draws the plots it is sent while this process writes the
rest of the record; the run waits for them before its end note, so the run directory is
the same. Where the child cannot be started, or fails, the same functions draw the same
plots here, in this process. A job is ``("module:function", keywords)``; the keyword
``path`` is the file, written atomically.
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


@contextmanager
def written(path: Path) -> Iterator[Path]:
    """station.files.atomic_path for a file written while the run writes others beside it:
    its temporary, ``.<name>.plot-<pid><suffix>``, is one that atomic_path's clearing of a
    record file's stale temporaries (``.<stem>.tmp-*``: results.json beside results.png)
    never matches, and it clears only its own."""
    from station.files import fsync_dir

    for old in path.parent.glob(f".{path.name}.plot-*"):
        old.unlink(missing_ok=True)
    tmp = path.with_name(f".{path.name}.plot-{os.getpid()}{path.suffix}")
    try:
        yield tmp
        if tmp.exists():
            with tmp.open("rb") as f:
                os.fsync(f.fileno())
            os.replace(tmp, path)
            fsync_dir(path.parent)
    finally:
        tmp.unlink(missing_ok=True)


def draw_here(jobs: list[Job], raising: bool = False) -> list[str | None]:
    """Draw ``jobs`` in this process, each atomically to its keyword ``path``; per job None,
    or the line of the error that stopped it (``raising``: the error itself)."""
    done: list[str | None] = []
    for name, kw in jobs:
        try:
            module, _, function = name.partition(":")
            draw = getattr(importlib.import_module(module), function)
            with written(Path(kw["path"])) as tmp:
                draw(**{**kw, "path": tmp})
            done.append(None)
        except Exception as e:  # noqa: BLE001  # reported; the parent draws it again
            if raising:
                raise
            done.append(f"{name}: {type(e).__name__}: {e}".splitlines()[0])
    return done


class PlotWorker:
    """A child process that draws plot jobs: ``draw`` sends them, ``wait`` returns once
    every plot is written (drawing here what the child did not). ``modules``: those the
    child imports at once, while the run runs (the plotting functions' own)."""

    def __init__(self, *modules: str) -> None:
        self._jobs: list[Job] = []
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

    def draw(self, jobs: list[Job]) -> None:
        """Send ``jobs`` to the child (all of one day: the child draws one batch)."""
        self._jobs = list(jobs)
        p = self._proc
        if p is None or p.stdin is None:
            return
        try:
            p.stdin.write(pickle.dumps(self._jobs))
            p.stdin.close()
        except OSError:  # the child is gone: wait() draws them here
            self.close()

    def wait(self) -> None:
        """Every job's plot is written once this returns."""
        results: list[str | None] = [""] * len(self._jobs)
        p = self._proc
        if p is not None and p.stdout is not None:
            try:
                got = pickle.loads(p.stdout.read())
                if isinstance(got, list) and len(got) == len(self._jobs):
                    results = got
            except (OSError, EOFError, pickle.UnpicklingError):
                pass
            p.wait()
            self._proc = None
        again = [j for j, r in zip(self._jobs, results, strict=True) if r is not None]
        self._jobs = []
        if again:  # as the day drew them before: an error here is the day's
            draw_here(again, raising=True)

    def close(self) -> None:
        """End the child if it still runs (a day that stopped before its plots)."""
        p, self._proc = self._proc, None
        if p is not None and p.poll() is None:
            p.kill()
            p.wait()
        if p is not None:
            for f in (p.stdin, p.stdout):
                if f is not None:
                    try:
                        f.close()
                    except OSError:
                        pass


def main() -> None:
    """The child: import matplotlib and the modules named in argv now (while the run
    runs), then draw the one batch of jobs read from stdin and write each job's outcome to
    stdout."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401  # the import is the point: done before it is needed

    for module in sys.argv[1:]:
        importlib.import_module(module)

    data = sys.stdin.buffer.read()
    if not data:
        return
    sys.stdout.buffer.write(pickle.dumps(draw_here(pickle.loads(data))))
    sys.stdout.buffer.flush()


if __name__ == "__main__":
    main()
