"""The run journal: JSON Lines, only ever appended, each record written before the next.

Every record is written to the file as it is appended (a killed process loses nothing
appended); it is synced to the disk (group commit) at the records a resume builds on: a
block, a note, a failed step, a sheet saved outside a block (``held``: a block's sheets
go with its record), and at close. A step record is synced with the next of those: a
machine that crashes in between loses at most the steps of the chart in progress, which
the resume repeats anyway (replay re-executes them; skip mode repeats the incomplete
chart from its first step).

A new journal is created exclusively; a resumed one is checked line by line first
(``scan``) and then opened for appending, never rewritten. A killed process loses at most
the record it was writing: a torn last line (no newline, or not parseable) is copied to a
side file ``journal.jsonl.torn-<n>`` and only those bytes are cut off. Any other malformed
line refuses the resume naming ``file:line`` and leaves the file as it was. Sheet names in
the journal become file names, so they must be plain names (``SAFE_NAME``).
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from station.errors import UseError
from station.files import fsync_dir

KINDS = ("step", "sheet", "note", "block", "failed")
SYNCED_KINDS = frozenset(("sheet", "note", "block", "failed"))  # group-commit points
HELD_KINDS = frozenset(("sheet",))  # not synced on their own inside a block (``held``)
SAFE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+-]{0,127}")
TORN_SUFFIX = ".torn-"


class JournalError(UseError):
    """A journal that cannot be created or resumed; the message names the file (and line)
    (exit 2)."""


def _default(o: Any) -> Any:
    if hasattr(o, "model_dump"):
        return o.model_dump(mode="json")
    if hasattr(o, "tolist"):
        return o.tolist()
    raise TypeError(f"cannot journal {type(o).__name__}")


def dumps(rec: dict) -> str:
    """One record as its journal line (ASCII, sorted keys, no spaces)."""
    return json.dumps(rec, default=_default, sort_keys=True, separators=(",", ":"))


def is_safe_name(name: object) -> bool:
    """A sheet name usable as a file name inside the run directory (no path, no dot-file)."""
    return isinstance(name, str) and SAFE_NAME.fullmatch(name) is not None


def _is_str(rec: dict, key: str) -> bool:
    return isinstance(rec.get(key), str)


def _record_problem(rec: object, sheets_seen: set[str]) -> str | None:
    """Why ``rec`` is not a journal record (None: it is one)."""
    if not isinstance(rec, dict):
        return f"a JSON {type(rec).__name__}, not a record (an object)"
    kind = rec.get("kind")
    if kind not in KINDS:
        return f"unknown record kind {kind!r} (one of {', '.join(KINDS)})"
    if kind in ("step", "failed"):
        for key in ("chart", "step"):
            if not _is_str(rec, key):
                return f"{kind} record without a text {key!r}"
    if kind == "step":
        t = rec.get("t_sim")
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t):
            return "step record without a finite t_sim"
    if kind == "note" and not _is_str(rec, "event"):
        return "note record without a text 'event'"
    if kind == "sheet":
        if not is_safe_name(rec.get("name")):
            return (f"sheet name {rec.get('name')!r} is not a plain file name (it would "
                    "address a path outside the run directory)")
        if "data" not in rec:
            return "sheet record without data"
    if kind == "block":
        names = rec.get("sheets")
        if not _is_str(rec, "key") or "data" not in rec or not isinstance(names, list):
            return "block record without key, data and sheets"
        for name in names:
            if not is_safe_name(name):
                return (f"block {rec['key']!r} names sheet {name!r}, not a plain file name "
                        "(it would address a path outside the run directory)")
            if name not in sheets_seen:
                return f"block {rec['key']!r} names sheet {name!r}, which no earlier record saved"
        steps = rec.get("steps", [])
        if not isinstance(steps, list) or not all(_is_step(r) for r in steps):
            return (f"block {rec['key']!r} carries steps that are not step records "
                    "(number, text, done, finite t_sim)")
    return None


def _is_step(rec: object) -> bool:
    """A step of a check-sheet as a block journals it (``StepRecord``'s fields)."""
    if not isinstance(rec, dict) or not _is_str(rec, "number") or not _is_str(rec, "text"):
        return False
    t = rec.get("t_sim")
    return (isinstance(rec.get("done"), bool) and not isinstance(t, bool)
            and isinstance(t, (int, float)) and math.isfinite(t))


def _parse(line: bytes) -> object:
    """The JSON value of a line; ValueError (or RecursionError) when it is not JSON."""
    return json.loads(line.decode("utf-8"))


@dataclass
class Scan:
    """What a journal file holds: its whole records and, if any, its torn last line."""

    path: Path
    records: list[dict] = field(default_factory=list)
    lines: list[int] = field(default_factory=list)  # line number of each record
    good_bytes: int = 0  # length of the prefix of whole records
    torn: bytes = b""  # the torn last line (empty: none)
    torn_line: int = 0

    @property
    def complete(self) -> bool:
        """The run reached its end note."""
        return any(r["kind"] == "note" and r["event"] == "end" for r in self.records)

    @property
    def start(self) -> dict | None:
        """The first start note (the run's own arguments)."""
        return next((r for r in self.records
                     if r["kind"] == "note" and r["event"] == "start"), None)


def scan(path: Path) -> Scan:
    """Read and check every line of the journal at ``path`` without touching it.

    Raises ``JournalError`` naming ``path:line`` for a malformed line that is not the last
    one (or a last line that parses but is not a record), and for a missing file.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise JournalError(f"{path}: no journal there") from None
    except IsADirectoryError:
        raise JournalError(f"{path}: a directory, not a journal") from None
    except OSError as e:
        raise JournalError(f"{path}: cannot read the journal ({e.strerror})") from None
    out = Scan(path)
    parts = data.split(b"\n")
    tail = parts.pop()  # after the last newline: empty unless the last line is unterminated
    sheets_seen: set[str] = set()
    offset = 0
    for i, line in enumerate(parts, start=1):
        last = i == len(parts) and not tail
        try:
            rec = _parse(line)
        except (ValueError, RecursionError):
            if last:  # a whole line that does not parse, at the end: a torn write
                out.torn, out.torn_line = line + b"\n", i
                break
            raise JournalError(f"{path}:{i}: not a JSON record: "
                               f"{line[:60].decode('utf-8', 'replace')!r}") from None
        problem = _record_problem(rec, sheets_seen)
        if problem:
            raise JournalError(f"{path}:{i}: {problem}")
        assert isinstance(rec, dict)
        if rec["kind"] == "sheet":
            sheets_seen.add(rec["name"])
        out.records.append(rec)
        out.lines.append(i)
        offset += len(line) + 1
    if tail:
        out.torn, out.torn_line = tail, len(parts) + 1
    out.good_bytes = offset
    return out


def set_aside_torn(s: Scan) -> Path:
    """Copy the torn last line to the first free ``<journal>.torn-<n>`` (synced), then cut
    exactly those bytes off the journal. A kill in between leaves the journal as it was."""
    path = s.path
    if path.stat().st_size != s.good_bytes + len(s.torn):
        raise JournalError(f"{path}: changed while it was being resumed")
    n, fd = 1, -1
    while fd < 0:
        side = path.with_name(f"{path.name}{TORN_SUFFIX}{n}")
        try:
            fd = os.open(side, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
        except FileExistsError:
            n += 1
    try:
        _write_all(fd, s.torn)
        os.fsync(fd)
    finally:
        os.close(fd)
    fsync_dir(path.parent)
    os.truncate(path, s.good_bytes)
    fd = os.open(path, os.O_WRONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
    return side


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


class Journal:
    """An open journal: ``records`` are those it held when opened (resume) or none."""

    def __init__(self, path: Path, resume: bool = False) -> None:
        self.path = Path(path)
        self.records: list[dict] = []
        self.lines: list[int] = []
        self.torn_to: Path | None = None  # where a torn last line was set aside
        self._unsynced = False  # records written since the last fsync
        self._held = 0  # blocks open (``held``)
        if resume:
            if not self.path.is_file():
                raise JournalError(f"{self.path}: no journal there")
            self._fd = self._open(os.O_WRONLY | os.O_APPEND)
            try:
                s = scan(self.path)
                if s.torn:
                    self.torn_to = set_aside_torn(s)
            except BaseException:
                self.close()
                raise
            self.records, self.lines = s.records, s.lines
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            if self.path.exists() and self.path.stat().st_size > 0:
                raise JournalError(f"{self.path}: already holds a journal (resume it, or "
                                   "record elsewhere)")
            self._fd = self._open(os.O_WRONLY | os.O_APPEND | os.O_CREAT)
            fsync_dir(self.path.parent)

    def _open(self, flags: int) -> int:
        try:
            return os.open(self.path, flags | os.O_NOFOLLOW, 0o644)
        except OSError as e:
            raise JournalError(f"{self.path}: cannot open the journal ({e.strerror})") from None

    def append(self, rec: dict) -> None:
        """Write one record as one line; sync the file at a group-commit point (a record
        of ``SYNCED_KINDS``: everything written before it becomes durable with it)."""
        _write_all(self._fd, (dumps(rec) + "\n").encode("ascii"))
        self._unsynced = True
        kind = rec.get("kind")
        if kind in SYNCED_KINDS and not (self._held and kind in HELD_KINDS):
            self.sync()

    @contextmanager
    def held(self) -> Iterator[None]:
        """Inside a block: its sheets are synced with the block's own record, which follows
        them (a resume restores a block's sheets only through that record)."""
        self._held += 1
        try:
            yield
        finally:
            self._held -= 1

    def sync(self) -> None:
        """Make every record written so far durable (nothing to do if it already is)."""
        if self._fd >= 0 and self._unsynced:
            os.fsync(self._fd)
            self._unsynced = False

    def close(self) -> None:
        if self._fd >= 0:
            try:
                self.sync()
            finally:
                os.close(self._fd)
                self._fd = -1
