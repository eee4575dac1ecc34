"""The tape library: a directory of parameter tapes (Chart I-7) indexed by the Chart I-8
parameters they were made from.

I-3 runs the parameter evaluation only when an input of the Alignment Parameter Evaluation
Sheet changes; the reports say nothing of how the reels are kept. Here (our design, see
docs/alignment-options.md) the reels are JSON files in one directory with an index
(``index.json``: reel id, file, K, Delta t, eps_t, the run that filed it). A lookup takes the
reels of the experiment's K, Delta t and eps_t from the index and gives the first whose sheet
passes the operator's check (``check_tape``); otherwise the procedure makes a tape and files
it. The index is a cache: when it is missing, unreadable or does not list exactly the files
present, it is rebuilt from the reels themselves, so two runs filing at once lose nothing.
Each reel names the run that filed it (``Tape.filed_by``); a reel filed by the run now
looking (``run_uid``) is not offered to it, so a resumed run takes the same path it took
before the interruption.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from pydantic import ValidationError

from procedures.isu.alignment.estimation import LevelParams
from procedures.isu.alignment.parameter_sheet import Tape, check_tape, t1_angle_rad, write_tape
from station.files import write_bytes

INDEX = "index.json"
INDEX_FORMAT = "isu-station tape library 1"
ARCSEC_PER_RAD = 180.0 / math.pi * 3600.0


@dataclass(frozen=True)
class Reel:
    """One indexed reel: its identification, file (in the library) and key parameters."""

    reel_id: str
    file: str
    K: int
    dt: float
    eps_t: float
    filed_by: str | None = None

    def key(self) -> tuple[int, float, float]:
        return self.K, self.dt, self.eps_t


@dataclass(frozen=True)
class Lookup:
    """What a lookup found: the tape and its file, or why no reel would do."""

    tape: Tape | None
    file: Path | None
    why_not: str | None = None
    t1_offset_arcsec: float | None = None  # found: the reel's T1 against the experiment's


class TapeLibrary:
    """A directory of tapes; ``run_uid``: the run using it (its own reels are not offered)."""

    def __init__(self, root: str | Path, run_uid: str | None = None) -> None:
        self.root = Path(root)
        self.run_uid = run_uid

    # ------------------------------------------------------------------ reading
    def reels(self) -> list[Reel]:
        """The indexed reels (the index rebuilt when it does not match the directory)."""
        files = sorted(p.name for p in self.root.glob("*.json") if p.name != INDEX)
        index = self._read_index()
        if index is not None and sorted(r.file for r in index) == files:
            return index
        return self._rebuild(files)

    def _read_index(self) -> list[Reel] | None:
        try:
            data = json.loads((self.root / INDEX).read_text())
            if data.get("format") != INDEX_FORMAT:
                return None
            return [Reel(**r) for r in data["reels"]]
        except (OSError, ValueError, TypeError, KeyError, AttributeError):
            return None

    def _rebuild(self, files: list[str]) -> list[Reel]:
        reels = []
        for name in files:
            tape = self._load(self.root / name)
            if tape is not None:
                reels.append(_reel(tape, name))
        self._write_index(reels)
        return reels

    @staticmethod
    def _load(path: Path) -> Tape | None:
        try:
            return Tape.model_validate_json(path.read_bytes())
        except (OSError, ValidationError):
            return None  # not a reel: a stray file in the directory is left alone

    def find(self, params: LevelParams) -> Lookup:
        """The first reel whose sheet passes ``check_tape`` for ``params``."""
        if not self.root.is_dir():
            return Lookup(None, None, f"no library at {self.root}")
        key = (params.K, params.dt, params.eps_t)
        candidates = [r for r in self.reels()
                      if r.key() == key and (self.run_uid is None or r.filed_by != self.run_uid)]
        if not candidates:
            return Lookup(None, None, f"no reel for K = {params.K}, Delta t = {params.dt:g} s, "
                                      f"eps_t = {params.eps_t:g} s")
        why = ""
        for r in candidates:
            tape = self._load(self.root / r.file)
            if tape is None:
                continue
            try:
                check_tape(tape, params)
            except ValueError as e:
                why = why or f"{r.reel_id}: {e}"
                continue
            offset = t1_angle_rad(tape.params.t1, params.t1) * ARCSEC_PER_RAD
            return Lookup(tape, self.root / r.file, None, offset)
        return Lookup(None, None, why or "no readable reel")

    # ------------------------------------------------------------------ filing
    def file(self, tape: Tape) -> Path:
        """File ``tape`` as ``<reel id>.json`` (the same reel filed again is not doubled)."""
        self.root.mkdir(parents=True, exist_ok=True)
        name = f"{tape.sheet.reel_id}.json"
        path = self.root / name
        if not path.exists():
            tape = tape.model_copy(update={"filed_by": self.run_uid})
            write_tape(tape, path)
        else:
            tape = self._load(path) or tape
        reels = [r for r in self.reels() if r.file != name]
        reels.append(_reel(tape, name))
        self._write_index(sorted(reels, key=lambda r: r.file))
        return path

    def _write_index(self, reels: list[Reel]) -> None:
        if not self.root.is_dir():
            return
        data = {"format": INDEX_FORMAT, "reels": [r.__dict__ for r in reels]}
        write_bytes(self.root / INDEX, json.dumps(data, indent=1).encode("utf-8"))


def _reel(tape: Tape, name: str) -> Reel:
    p = tape.sheet.params
    return Reel(tape.sheet.reel_id, name, p.K, p.dt, p.eps_t, tape.filed_by)
