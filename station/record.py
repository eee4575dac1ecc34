"""Writing a run's record: every file atomically, every name inside the run directory.

A file of the record is written to a temporary file in its own directory, synced and
renamed over the old one, and the directory is synced: a kill leaves the old file or the
new one, never a mix. Sheets go to DIR/sheets/<name>.json under plain names only.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from procedures.journal import dumps, fsync_dir, is_safe_name
from procedures.runner import Run

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


def _clear_stale(path: Path) -> None:
    """Temporaries of ``path`` left by a killed writer."""
    for old in path.parent.glob(f".{path.stem}{TMP_MARK}*"):
        old.unlink(missing_ok=True)


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


def write_json(path: Path, obj: Any, sync_dir: bool = True) -> None:
    """A JSON file of the record (indented, sorted keys), atomically."""
    write_bytes(path, json.dumps(obj, indent=1, sort_keys=True).encode("utf-8"), sync_dir)


def sheet_path(out: Path, name: str) -> Path:
    """DIR/sheets/<name>.json; ValueError for a name that is not a plain file name."""
    if not is_safe_name(name):
        raise ValueError(f"sheet name {name!r} is not a plain file name: it would address a "
                         "path outside the run directory")
    return Path(out) / "sheets" / f"{name}.json"


def write_sheets(out: Path, run: Run) -> None:
    """Every sheet of ``run`` as DIR/sheets/<name>.json (each atomically; one directory
    sync at the end)."""
    paths = {name: sheet_path(out, name) for name in run.sheets}
    (Path(out) / "sheets").mkdir(parents=True, exist_ok=True)
    for name, model in run.sheets.items():
        write_json(paths[name], json.loads(dumps({"x": model}))["x"], sync_dir=False)
    fsync_dir(Path(out) / "sheets")


def write_results(out: Path, res: dict) -> None:
    """DIR/results.json, atomically."""
    write_json(Path(out) / "results.json", res)
