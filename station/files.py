"""Files written whole or not at all: the primitive under the journal, tapes and records.

A file is written to a temporary name in its own directory, synced and renamed over the
old one, and the directory is synced: a kill leaves the old file or the new one, never a
mix, and a new or renamed entry survives a crash.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def fsync_dir(d: Path) -> None:
    """Make a directory's entries (a new or renamed file) durable."""
    fd = os.open(d, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


TMP_MARK = ".tmp-"


def _temp_for(path: Path) -> Path:
    """The temporary name of ``path``: a dot-file beside it, keeping its suffix (matplotlib
    picks the format from it) and not matching ``*.json`` unless the target does."""
    return path.with_name(f".{path.stem}{TMP_MARK}{os.getpid()}{path.suffix}.part"
                          if path.suffix == ".json" else
                          f".{path.stem}{TMP_MARK}{os.getpid()}{path.suffix}")


def _sync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def clear_prefixed(directory: Path, prefix: str) -> None:
    """Remove the entries of ``directory`` whose names begin with ``prefix`` (temporaries
    left by a killed writer). A literal prefix, not a glob pattern: one directory listing,
    no pattern compiled per file (issue 17: 45 record files a day); an unreadable or
    missing directory holds none (its write then says what is wrong)."""
    try:
        with os.scandir(directory) as entries:
            stale = [e.path for e in entries if e.name.startswith(prefix)]
    except OSError:
        return
    for old in stale:
        Path(old).unlink(missing_ok=True)


def _clear_stale(path: Path) -> None:
    """Temporaries of ``path`` left by a killed writer."""
    clear_prefixed(path.parent, f".{path.stem}{TMP_MARK}")


@contextmanager
def atomic_path(path: Path, sync_dir: bool = True) -> Iterator[Path]:
    """Yield a temporary path to write ``path``'s new content to; on success it is synced
    and renamed over ``path`` (nothing happens if the writer made no file)."""
    path = Path(path)
    _clear_stale(path)
    tmp = _temp_for(path)
    try:
        yield tmp
        if tmp.exists():
            _sync_file(tmp)
            os.replace(tmp, path)
            if sync_dir:
                fsync_dir(path.parent)
    finally:
        tmp.unlink(missing_ok=True)


def write_bytes(path: Path, data: bytes, sync_dir: bool = True) -> None:
    """``path`` now holds ``data``, atomically."""
    with atomic_path(path, sync_dir) as tmp:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
        finally:
            os.close(fd)
