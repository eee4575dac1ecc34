"""Append-only run journal: JSON Lines, flushed and synced record by record.

A killed process loses at most the record being written; ``--resume`` reads it back.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any


def _default(o: Any):
    if hasattr(o, "model_dump"):
        return o.model_dump(mode="json")
    if hasattr(o, "tolist"):
        return o.tolist()
    raise TypeError(f"cannot journal {type(o).__name__}")


def dumps(rec: dict) -> str:
    return json.dumps(rec, default=_default, sort_keys=True, separators=(",", ":"))


class Journal:
    def __init__(self, path: Path, resume: bool = False) -> None:
        self.path = Path(path)
        self.records: list[dict] = []
        if resume and self.path.exists():
            with open(self.path, encoding="utf-8") as f:
                for line in f:
                    line = line.strip()
                    if not line:
                        continue
                    try:
                        self.records.append(json.loads(line))
                    except json.JSONDecodeError:
                        break  # a record cut by the kill: everything after it is lost
            # rewrite without the torn tail so appends start on a clean line
            with open(self.path, "w", encoding="utf-8") as f:
                for r in self.records:
                    f.write(dumps(r) + "\n")
        elif not resume:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.path.write_text("", encoding="utf-8")
        self._f = open(self.path, "a", encoding="utf-8")  # noqa: SIM115

    def append(self, rec: dict) -> None:
        self._f.write(dumps(rec) + "\n")
        self._f.flush()
        os.fsync(self._f.fileno())

    def close(self) -> None:
        self._f.close()
