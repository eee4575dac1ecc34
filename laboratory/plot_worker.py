"""A run's plots drawn beside the run (issue 17: plots off the critical path).

A child process started when a run starts imports matplotlib (and the plotting modules)
while the simulation runs, then draws the plots it is sent (as soon as their data exist)
while this process goes on; the run waits for them before its end note (only then are
they renamed into place), so the run directory is the same. Where the child cannot be
started, or fails, the same functions draw the same plots here, in this process. A job is
``("module:function", keywords)``; the keyword ``path`` is the file, written atomically.
A job's function may also return a value the run needs (``values``: the ESG's strategy
study, computed with its plot so that the run itself never imports scipy.optimize). A job
without a file (``compute``) is a computation the run does meanwhile on the second core
(the day's all-positions fit, during the closed forms' checks); the child pins its BLAS to
one thread as the run does (station.numerics), so a value is the same bits wherever it is
computed.
"""

from __future__ import annotations

import atexit
import importlib
import io
import os
import pickle
import select
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO

from laboratory.children import ended

Job = tuple[str, dict[str, Any]]  # "module:function", its keywords (one of them path)


def png_options() -> dict[str, Any]:
    """savefig's keywords for every plot of the record: zlib level 1 (the pixels are the
    same; Pillow's default 6 took a tenth of the results plot's drawing and the files are
    2-11 % larger at 1; issue 17). A fresh dict per call: savefig may keep what it is given.
    The record's plots also give their titles' y (1.0, the axes' top): matplotlib's
    automatic placement measures every tick label to lift a title clear of ticks on top,
    which none of them has (the same pixels; 0.006-0.033 s a plot)."""
    return {"pil_kwargs": {"compress_level": 1}}


def temporary(path: Path, pid: int | None = None) -> Path:
    """The temporary a plot of ``path`` is drawn to: ``.<name>.plot-<pid><suffix>``, one
    that station.files.atomic_path's clearing of a record file's stale temporaries
    (``.<stem>.tmp-*``: results.json beside results.png) never matches."""
    return path.with_name(f".{path.name}.plot-{pid or os.getpid()}{path.suffix}")


def _clear_stale(path: Path) -> None:
    """Plot temporaries of ``path`` left by a killed run."""
    from station.files import clear_prefixed

    clear_prefixed(path.parent, f".{path.name}.plot-")


def _installed(tmp: Path, path: Path, sync_dir: bool = True) -> None:
    """``tmp`` synced and renamed over ``path``, the directory synced (``sync_dir``: else
    the caller syncs it, once for the files it installs there)."""
    from station.files import fsync_dir

    with tmp.open("rb") as f:
        os.fsync(f.fileno())
    os.replace(tmp, path)
    if sync_dir:
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


def _draw(name: str, kw: dict[str, Any]) -> Any:
    module, _, function = name.partition(":")
    return getattr(importlib.import_module(module), function)(**kw)


def _line(name: str, e: Exception) -> str:
    return f"{name}: {type(e).__name__}: {e}".splitlines()[0]


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
            done.append(_line(name, e))
    return done


def _drawn_here(job: Job) -> Any:
    """``job`` drawn in this process, atomically to its ``path``; its function's value (an
    error is raised, as the run's own)."""
    name, kw = job
    with written(Path(kw["path"])) as tmp:
        return _draw(name, {**kw, "path": tmp})


Outcome = tuple[str, Any]  # ("ok", the function's value) or ("err", the error's line)


def _spawn(modules: tuple[str, ...]) -> subprocess.Popen[bytes] | None:
    """The child, importing ``modules`` at once (None: it could not be started). Its pipes
    keep the system's size: the child reads the batches sent as they come, whatever it is
    doing (``_batches_read_ahead``)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    try:
        return subprocess.Popen([sys.executable, "-m", "laboratory.plot_worker", *modules],
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL, env=env)
    except OSError:
        return None


class _Exact:
    """The child's answers read straight from the pipe, each ``read`` exactly what pickle
    asks for: none is read ahead into a buffer, where ``select`` would not see it (an answer
    already come would read as not come)."""

    def __init__(self, fd: int) -> None:
        self.fd = fd

    def read(self, n: int = -1) -> bytes:
        if n < 0:
            raise io.UnsupportedOperation("the child's answers are read by length")
        parts, left = [], n
        while left:
            got = os.read(self.fd, left)
            if not got:
                break  # the child is gone: pickle reports the answer cut short
            parts.append(got)
            left -= len(got)
        return b"".join(parts)

    def readinto(self, b: bytearray | memoryview) -> int:
        data = self.read(len(b))
        b[: len(data)] = data
        return len(data)

    def readline(self) -> bytes:
        line = bytearray()
        while not line.endswith(b"\n"):
            got = os.read(self.fd, 1)
            if not got:
                break
            line += got
        return bytes(line)


_early: subprocess.Popen[bytes] | None = None  # started by start_early, not yet adopted


def start_early(*modules: str) -> None:
    """Start the child now, as the command line names its command, so that its imports
    (matplotlib, the plotting modules: about 0.5 s) run beside the command's own instead of
    after them (issue 17); the run's first PlotWorker adopts it. A command that ends before
    it has one (a refused argument) ends the child at exit."""
    global _early
    if _early is None:
        _early = _spawn(modules)
        if _early is not None:
            atexit.register(_end_early)


def _adopted() -> subprocess.Popen[bytes] | None:
    """The early child, now the caller's (None: none was started, or it has died)."""
    global _early
    p, _early = _early, None
    if p is not None and p.poll() is not None:
        _ended(p)
        return None
    return p


def _end_early() -> None:
    p = _adopted()
    if p is not None:
        _ended(p)


def _ended(p: subprocess.Popen[bytes], reap_beside: bool = False) -> None:
    """``p`` killed (if it still runs), reaped, and its pipes closed. ``reap_beside``: the
    reaping (the kernel's teardown of the child's memory: 3-6 ms) is left to a thread, for
    a child that has nothing left to write (``PlotWorker.close``, the end of a run)."""
    if reap_beside:
        threading.Thread(target=ended, args=(p,), daemon=True).start()
        return
    ended(p)


class PlotWorker:
    """A child process that draws plot jobs: ``draw`` sends them, ``wait`` returns once
    every plot is written (drawing here what the child did not). ``modules``: those the
    child imports at once, while the run runs (the plotting functions' own).

    The child draws each plot to a temporary beside its file; only ``wait`` renames them
    into place, so a run that stops before it (``close``) leaves no plot it would not have
    left when it drew them itself, at the same point."""

    def __init__(self, *modules: str) -> None:
        self._jobs: list[Job] = []
        self._temps: list[Path | None] = []  # None: a computation (no file)
        self._sent: dict[int, bytes] = {}  # a computation's job as sent (its arguments then)
        self._batches: list[range] = []  # the jobs of each batch sent
        self._outcomes: list[Outcome | None] = []  # per job, once the child answered
        self._here: set[int] = set()  # jobs drawn in this process already (``values``)
        self._answered = 0  # batches the child has answered
        # a child started early (start_early) imports whatever it lacks at its first job
        self._proc: subprocess.Popen[bytes] | None = _adopted() or _spawn(modules)

    def __enter__(self) -> PlotWorker:
        return self

    def __exit__(self, kind: type[BaseException] | None, e: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def draw(self, jobs: list[Job], more: bool = False) -> int:
        """Send ``jobs`` to the child to draw while this process goes on, in the order
        sent; ``more``: other batches follow (a run sends a plot as soon as its data
        exist, and the rest later), else this is the last one. Returns the batch's number
        (``values``)."""
        jobs = list(jobs)
        paths = [Path(kw["path"]) for _, kw in jobs]
        for path in paths:
            _clear_stale(path)
        temps = [temporary(path) for path in paths]
        first = len(self._jobs)
        self._jobs += jobs
        self._temps += temps
        self._outcomes += [None] * len(jobs)
        self._batches.append(range(first, len(self._jobs)))
        self._send(pickle.dumps([(name, {**kw, "path": tmp})
                                 for (name, kw), tmp in zip(jobs, temps, strict=True)]),
                   last=not more)
        return len(self._batches) - 1

    def _send(self, batch: bytes, last: bool = False) -> None:
        """One pickled batch to the child (``last``: then its stdin is closed); where the
        child is gone or takes no more, ``values`` and ``wait`` do the jobs here."""
        p = self._proc
        if p is None or p.stdin is None or p.stdin.closed:
            return
        try:
            p.stdin.write(batch)
            p.stdin.flush()
            if last:
                p.stdin.close()
        except OSError:  # the child is gone
            self._end_child()

    def compute(self, job: str, kwargs: dict[str, Any], race: bool = False
                ) -> Callable[[], Any]:
        """Send the computation ``job`` (``"module:function"``, no file) to the child on its
        arguments as they are now; the returned callable gives its value (computed here, on
        those same arguments, if the child could not: an error then is the run's).
        ``race``: the callable does not wait for a child still busy (with the plots sent
        before): unless its value has come or the child is on it, it computes it here at
        once (the same bits)."""
        first = len(self._jobs)
        sent = pickle.dumps([(job, kwargs)])  # the arguments now, whatever they become
        self._jobs.append((job, {}))
        self._sent[first] = sent
        self._temps.append(None)
        self._outcomes.append(None)
        self._batches.append(range(first, first + 1))
        batch = len(self._batches) - 1
        self._send(sent)
        if race:
            return lambda: self._first(batch)
        return lambda: self.values(batch)[0]

    def _first(self, batch: int) -> Any:
        """The value of the computation ``batch``: the child's if it has come or the child
        is on it (it has answered every batch before: it began no later than this process
        would), else made here now (its answer, when it comes, is read and left)."""
        if self._proc is None or self._answered_now(batch) or self._answered == batch:
            return self.values(batch)[0]
        (i,) = self._batches[batch]
        return self._computed_here(i)

    def _computed_here(self, i: int) -> Any:
        """Computation ``i`` made in this process on its arguments as they were sent (its
        error is the run's)."""
        ((name, kw),) = pickle.loads(self._sent[i])
        value = _draw(name, kw)
        self._here.add(i)
        return value

    def _answered_now(self, batch: int) -> bool:
        """Whether the child has answered every batch up to ``batch``, reading the answers
        that have come without waiting for more (each is read by exact length, ``_Exact``:
        an answer come is in the pipe, where ``select`` sees it)."""
        while self._answered <= batch:
            p = self._proc
            if p is None or p.stdout is None:
                return False
            try:
                ready, _, _ = select.select([p.stdout], [], [], 0.0)
            except (OSError, ValueError):
                return False
            if not ready:
                return False
            self._read_answers(self._answered)  # its first bytes are here: the rest follow
        return True

    def _read_answers(self, upto: int) -> None:
        """The child's answers to every batch up to ``upto`` (the child gone: none)."""
        while self._answered <= upto:
            p = self._proc
            if p is None or p.stdout is None:
                return
            batch = self._batches[self._answered]
            try:
                got = pickle.load(_Exact(p.stdout.fileno()))
                if not (isinstance(got, list) and len(got) == len(batch)):
                    raise EOFError
            except (OSError, EOFError, pickle.UnpicklingError):
                self._end_child()
                return
            for i, outcome in zip(batch, got, strict=True):
                self._outcomes[i] = outcome
            self._answered += 1

    def values(self, batch: int) -> list[Any]:
        """What the functions of batch ``batch`` returned (each drawn here if the child
        could not: an error then is the run's); their plots are put in place at ``wait``."""
        self._read_answers(batch)
        out = []
        for i in self._batches[batch]:
            outcome, tmp = self._outcomes[i], self._temps[i]
            if outcome is not None and outcome[0] == "ok" and (tmp is None or tmp.exists()):
                out.append(outcome[1])
            elif tmp is None:
                out.append(self._computed_here(i))
            else:
                tmp.unlink(missing_ok=True)
                out.append(_drawn_here(self._jobs[i]))
                self._here.add(i)
        return out

    def wait(self, meanwhile: Callable[[], None] | None = None, keep: bool = False) -> None:
        """Every job's plot is in place once this returns; ``meanwhile`` runs here while
        the child may still be drawing (work the run needs next, e.g. the report's
        template). ``keep``: the child stays for later computations (the report, once the
        record is closed: ``report.html.report_after``), else it ends here."""
        p = self._proc
        if not keep and p is not None and p.stdin is not None and not p.stdin.closed:
            try:
                p.stdin.close()  # no more batches
            except OSError:
                pass
        if meanwhile is not None:
            meanwhile()
        self._read_answers(len(self._batches) - 1)
        if not keep:
            self._end_child()
        again = []
        dirs: dict[Path, None] = {}  # each synced once, after every file put there
        for i, (job, tmp) in enumerate(zip(self._jobs, self._temps, strict=True)):
            outcome = self._outcomes[i]
            if i in self._here or tmp is None:  # drawn here, or a computation (no file)
                continue
            if outcome is not None and outcome[0] == "ok" and tmp.exists():
                path = Path(job[1]["path"])
                _installed(tmp, path, sync_dir=False)
                dirs[path.parent] = None
            else:
                tmp.unlink(missing_ok=True)
                again.append(job)
        if dirs:
            from station.files import fsync_dir

            for d in dirs:
                fsync_dir(d)
        self._forget()
        if again:  # as the run drew them before: an error here is the run's
            draw_here(again, raising=True)

    def _forget(self) -> None:
        self._jobs, self._temps, self._batches, self._outcomes = [], [], [], []
        self._sent = {}
        self._here, self._answered = set(), 0

    def _end_child(self, reap_beside: bool = False) -> None:
        p, self._proc = self._proc, None
        if p is not None:
            _ended(p, reap_beside)

    def close(self) -> None:
        """End the child if it still runs and remove what it drew but was not installed
        (a run that stopped before its plots). A child that has answered every job is
        killed and left to a thread to reap (nothing of it is left to write: the end of
        every run, whose process need not wait for the child's teardown, issue 17)."""
        self._end_child(reap_beside=self._answered == len(self._batches))
        for tmp in self._temps:
            if tmp is not None:
                tmp.unlink(missing_ok=True)
        self._forget()


def _batches_read_ahead(source: BinaryIO) -> Iterator[list[Job]]:
    """The batches sent, in order, read from ``source`` by a thread as they come, not when
    the last is drawn: a child blocked writing an answer the run has not yet read (a pipe
    holds 64 KB where it cannot be widened) still takes what the run sends, so the run's
    send never waits on it (both waiting: the day hung with a slow child)."""
    import queue

    come: queue.SimpleQueue[list[Job] | BaseException | None] = queue.SimpleQueue()

    def read() -> None:
        while True:
            try:
                come.put(pickle.load(source))
            except EOFError:
                come.put(None)
                return
            except BaseException as e:  # noqa: BLE001  # raised where the batches are drawn
                come.put(e)
                return

    threading.Thread(target=read, name="batches", daemon=True).start()
    while (batch := come.get()) is not None:
        if isinstance(batch, BaseException):
            raise batch
        yield batch


def main() -> None:
    """The child: import matplotlib and the modules named in argv now (while the run
    runs), then draw each batch of jobs read from stdin as it comes and answer it on stdout
    (per job, the function's value or the line of its error)."""
    from laboratory import startup

    startup.defer()  # as the script does: the imports make no garbage
    from station.numerics import pin_blas_threads

    pin_blas_threads()  # as the run's own computations: the same bits here as there
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401  # the import is the point: done before it is needed

    for module in sys.argv[1:]:
        importlib.import_module(module)
    startup.resume()  # what the imports made frozen; the plots' garbage is collected

    out = sys.stdout.buffer
    for batch in _batches_read_ahead(sys.stdin.buffer):
        done: list[Outcome] = []
        for name, kw in batch:  # to the parent's temporaries: it renames them
            try:
                done.append(("ok", _draw(name, kw)))
            except Exception as e:  # noqa: BLE001  # reported; the parent draws it again
                done.append(("err", _line(name, e)))
        out.write(pickle.dumps(done))  # each batch answered as soon as it is drawn
        out.flush()


if __name__ == "__main__":
    from laboratory.process_exit import finish

    main()
    finish(0)  # without the interpreter's teardown: a run need not be slowed by it
