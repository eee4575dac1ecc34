"""Where a command's record goes: a new run directory, or the interrupted run it resumes.

A new run goes to a new or empty directory (one that holds a record can only be resumed,
nothing else may be mixed with a record); each run
without ``--out`` gets a fresh ``<base>/<UTC time>-seed<N>``; ``--resume DIR`` needs DIR's
journal, whole but for a torn last line, and the run's own arguments (its start note). All
of this is decided before anything is written, and every refusal is one ``RunDirError``
line naming the directory.
"""

from __future__ import annotations

import datetime as dt
import fcntl
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, ClassVar

from procedures.journal import TORN_SUFFIX, Journal, Scan, scan
from procedures.runner import Run
from station.errors import UseError

JOURNAL = "journal.jsonl"
RECORD_NAMES = ("journal.jsonl", "sheets", "tapes", "results.json", "gyrocompass.json",
                "esg.json", "gyrocompass_analysis.json", "nonlinearity.png",
                "gyrocompass.png", "esg_calibration.png", "esg_strategy.png")
# the start note's "test" of the CIGTF and ESG runs -> their command
TESTS = {"gyrocompass": "gyrocompass-test", "esg-calibration": "esg-calibration"}


class RunDirError(UseError):
    """A run directory a command may not use as asked; one line naming it (exit 2)."""


def holds_record(d: Path) -> bool:
    """``d`` holds (part of) a run's record: a journal, sheets, results, plots or tapes."""
    d = Path(d)
    return (any((d / n).exists() or (d / n).is_symlink() for n in RECORD_NAMES)
            or any(d.glob(f"{JOURNAL}{TORN_SUFFIX}*")))


def check_new(out: Path) -> None:
    """``out`` may receive a new run: it is new or an empty directory. Refused: a record
    (to be resumed instead), any other content (a run must not mix with it), a file, a
    path through a file."""
    out = Path(out)
    if out.is_dir():
        if holds_record(out):
            raise RunDirError(f"{out} already holds a run's record and was left untouched: "
                              f"continue that run with --resume {out}, or choose another --out")
        if any(out.iterdir()):
            raise RunDirError(f"--out {out} is not empty: a new run needs a new or empty "
                              "directory (its record must not mix with other files)")
        return
    if out.exists() or out.is_symlink():
        raise RunDirError(f"--out {out} is an existing file, not a run directory")
    for parent in out.parents:
        if parent.exists():
            if not parent.is_dir():
                raise RunDirError(f"--out {out}: {parent} is a file, not a directory")
            break


def fresh(base: Path, seed: int, now: dt.datetime | None = None) -> Path:
    """Claim a new ``base/<UTC yyyymmddTHHMMSSZ>-seed<N>`` (``-2``, ``-3``... when a run of
    the same second has it): created here, empty."""
    stamp = (now or dt.datetime.now(dt.UTC)).strftime("%Y%m%dT%H%M%SZ")
    create(base)
    k = 1
    while True:
        d = Path(base) / (f"{stamp}-seed{seed}" + (f"-{k}" if k > 1 else ""))
        try:
            d.mkdir()
            return d
        except FileExistsError:
            k += 1
        except OSError as e:
            raise RunDirError(f"cannot create the run directory {d}: {e.strerror}") from None


def create(out: Path) -> None:
    """Make ``out`` (and its parents); RunDirError when the place is not writable."""
    try:
        Path(out).mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise RunDirError(f"cannot create the run directory {out}: {e.strerror}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise RunDirError(f"cannot write in the run directory {out}: permission denied")


def inspect_resume(d: Path) -> Scan:
    """The journal of the run to resume in ``d``, checked line by line (nothing changed)."""
    d = Path(d)
    if not d.exists():
        raise RunDirError(f"--resume {d}: no such directory")
    if not d.is_dir():
        raise RunDirError(f"--resume {d}: not a directory")
    if not (d / JOURNAL).is_file():
        raise RunDirError(f"--resume {d}: no journal ({JOURNAL}) there, nothing to resume")
    return scan(d / JOURNAL)


def resumed_args(s: Scan, given: dict[str, Any], command: str) -> dict[str, Any]:
    """The run's arguments: those of its start note, where the command line gives none;
    RunDirError when one given differs (the resume would not continue the same run)."""
    start = s.start
    if start is None:
        return dict(given)
    recorded_command = start.get("command") or TESTS.get(str(start.get("test")), "day")
    if recorded_command != command:
        raise RunDirError(f"{s.path} is the journal of a `station {recorded_command}` run, "
                          f"not of `station {command}`")
    out = {}
    for key, value in given.items():
        recorded = start.get(key)
        if isinstance(recorded, list) and not recorded:
            recorded = None  # [] = every chart / position
        if value is None:
            out[key] = recorded
        elif recorded is not None and _same(value) != _same(recorded):
            raise RunDirError(f"--{key.replace('_', '-')} {_show(value)} differs from the run "
                              f"being resumed ({_show(recorded)}, {s.path}): leave it out")
        else:
            out[key] = value
    return out


def _same(v: Any) -> Any:
    return sorted(v) if isinstance(v, (list, tuple)) else v


def _show(v: Any) -> str:
    return " ".join(map(str, v)) if isinstance(v, (list, tuple)) else str(v)


@contextmanager
def recording(out: Path) -> Iterator[None]:
    """Hold ``out`` for one run: a second run recording in it at the same time is refused."""
    fd = os.open(out, os.O_RDONLY | os.O_DIRECTORY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise RunDirError(f"{out}: another run is recording in it now") from None
        yield
    finally:
        os.close(fd)


def prepare(out: Path, resume: bool, links: Path | None = None) -> Scan | None:
    """Refuse, before anything is written, a directory this run may not record in; the
    journal's scan when resuming."""
    if not resume:
        check_new(out)
        return None
    s = inspect_resume(out)
    if s.complete:
        raise RunComplete(f"{out}: that run is complete (its journal holds the end note): "
                          "nothing to resume")
    starts = [r for r in s.records if r["kind"] == "note" and r["event"] == "start"]
    served = bool(starts) and (starts[-1].get("session") is not None
                               or starts[-1].get("served") is not None)
    if served and links is None:
        raise RunDirError(f"{out} was recorded over links (a served rack): resume it with "
                          "--links, where completed work is restored")
    return s


class RunComplete(RunDirError):
    """``--resume`` of a run that already ended: nothing to do (exit 0, the message on
    stdout)."""

    exit_code: ClassVar[int] = 0


@contextmanager
def opened_journal(out: Path, resume: bool) -> Iterator[Journal]:
    """The run directory created and held, its journal new or resumed (a torn last line
    set aside); closed however the run ends."""
    create(out)
    with recording(out):
        journal = Journal(Path(out) / JOURNAL, resume=resume)
        try:
            yield journal
        finally:
            journal.close()


def resume_note(run: Run) -> None:
    """The resume's own record in the journal: how, from how many records, where a torn
    last line went (history only: a replay never compares notes)."""
    j = run.journal
    j.append({"kind": "note", "event": "resume", "mode": run.resume, "records": len(j.records),
              "torn_line_to": j.torn_to.name if j.torn_to else None,
              "wall": dt.datetime.now(dt.UTC).isoformat(timespec="seconds")})
