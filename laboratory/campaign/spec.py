"""A campaign's spec (SPEC.toml): the command, its options, seeds and sweeps, and its tasks.

A task is one run of the command: its index, its run seed and its sweep values. Seeds come
from ``numpy.random.SeedSequence(seed).spawn``: task i's seed and random draws depend on the
campaign seed and i only, so a campaign is reproducible and a task's result does not depend
on which worker runs it, nor on how many tasks the campaign has.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from station.errors import UseError

# command -> its laboratory (the run functions of laboratory.virtual)
COMMANDS = {"day": "isu", "align": "isu", "gyrocompass-test": "cigtf",
            "esg-calibration": "esg"}
PLAN_PREFIX = "plan."  # sweep paths into the day plan (procedures/isu/plan.py), not the config
LAB_PREFIX = "lab."  # a random laboratory's draws (columns only, not overrides)
LAB_COLUMNS = tuple(LAB_PREFIX + n for n in ("latitude_deg", "longitude_deg", "gyro_noise",
                                             "accel_noise", "pier_noise", "frequency_error",
                                             "drift_per_day", "table_noise", "reading_noise",
                                             "vibration_noise"))

Scalar = float | int | bool | str


class SpecError(UseError, ValueError):
    """A campaign spec that cannot be run (one line naming the file and field)."""


class LaboratorySpec(BaseModel):
    """``[laboratory]``: each task on a random admissible laboratory (issue 19;
    laboratory/isu/random_lab.py), drawn from the task's own SeedSequence."""

    model_config = ConfigDict(defer_build=True, extra="forbid", frozen=True)

    random: bool = False
    redraw_isu: bool = True  # every ISU coefficient at 0.3-3x with random sign
    noise: float | None = Field(None, gt=0, le=10.0)  # fix every noise factor (None: drawn)


class CampaignSpec(BaseModel):
    """SPEC.toml: see docs/campaigns.md."""

    model_config = ConfigDict(defer_build=True, extra="forbid", frozen=True)

    command: str
    seeds: int = Field(1, ge=1, le=1_000_000)  # tasks per grid point
    seed: int = Field(0, ge=0)  # the campaign seed
    config: str | None = None  # a station config (relative to the spec); None: the default
    options: dict[str, Any] = {}  # the command's options (day: only, positions, align, ...)
    grid: dict[str, list[Scalar]] = {}  # every combination of these values
    random: dict[str, tuple[float, float]] = {}  # uniform draws per task in [low, high]
    laboratory: LaboratorySpec = LaboratorySpec()  # [laboratory] random = true (issue 19)

    @field_validator("command")
    @classmethod
    def _known(cls, v: str) -> str:
        if v not in COMMANDS:
            raise ValueError(f"unknown command {v!r} (known: {', '.join(COMMANDS)})")
        return v

    @field_validator("grid")
    @classmethod
    def _lists(cls, v: dict[str, list[Scalar]]) -> dict[str, list[Scalar]]:
        for path, values in v.items():
            if not values:
                raise ValueError(f"grid {path!r}: no values")
        return v

    @field_validator("random")
    @classmethod
    def _ranges(cls, v: dict[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
        for path, (lo, hi) in v.items():
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                raise ValueError(f"random {path!r}: [{lo}, {hi}] is not a range")
        return v

    @model_validator(mode="after")
    def _random_lab(self) -> CampaignSpec:
        if self.laboratory.random and COMMANDS[self.command] != "isu":
            raise ValueError(f"laboratory.random: a random laboratory is the isu "
                             f"laboratory's (day, align), not {self.command}'s")
        return self

    @property
    def lab(self) -> str:
        return COMMANDS[self.command]

    def document(self) -> dict[str, Any]:
        """The spec as JSON (``[laboratory]`` only when set: older specs keep their digest)."""
        doc = self.model_dump(mode="json")
        if self.laboratory == LaboratorySpec():
            del doc["laboratory"]
        return doc

    def sweep_paths(self) -> list[str]:
        """The sweep's dotted paths: grid first, then random (the Parquet's setting columns),
        then a random laboratory's draws (``lab.*``)."""
        paths = list(self.grid) + [p for p in self.random if p not in self.grid]
        return paths + list(LAB_COLUMNS) if self.laboratory.random else paths

    def points(self) -> list[dict[str, Scalar]]:
        """The grid's points (one empty point without a grid)."""
        keys = list(self.grid)
        return [dict(zip(keys, combo, strict=True))
                for combo in itertools.product(*(self.grid[k] for k in keys))]

    def n_tasks(self) -> int:
        return len(self.points()) * self.seeds

    def digest(self) -> str:
        """Of the spec's content: a resume runs only the campaign it started."""
        blob = json.dumps(self.document(), sort_keys=True).encode()
        return hashlib.sha256(blob).hexdigest()[:16]


@dataclass(frozen=True)
class Task:
    """One run of a campaign: index, run seed, sweep values (dotted path -> value)."""

    index: int
    seed: int
    values: dict[str, Scalar]


def lab_rng(spec: CampaignSpec, index: int) -> np.random.Generator:
    """Task ``index``'s random laboratory stream: child 1 of the task's SeedSequence (child
    0 is its ``[random]`` draws), whatever the worker and the number of tasks."""
    return np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=(index, 1)))


def lab_columns(spec: CampaignSpec, index: int) -> dict[str, Scalar]:
    """Task ``index``'s random laboratory as ``lab.*`` columns (empty without one)."""
    if not spec.laboratory.random:
        return {}
    from laboratory.isu.random_lab import draw
    from station.config.isu import default_dict

    lab = draw(lab_rng(spec, index), default_dict(), redraw_isu=spec.laboratory.redraw_isu,
               noise=spec.laboratory.noise)
    return {LAB_PREFIX + k: v for k, v in lab.describe().items()}


def tasks(spec: CampaignSpec) -> list[Task]:
    """Every task of ``spec``, grid point major, seed minor."""
    points = spec.points()
    n = len(points) * spec.seeds
    children = np.random.SeedSequence(spec.seed).spawn(n)
    out = []
    for i, child in enumerate(children):
        values: dict[str, Scalar] = dict(points[i // spec.seeds])
        run_seed = int(child.generate_state(1)[0])  # 32 bits: every laboratory's seed
        if spec.random:
            rng = np.random.default_rng(child.spawn(1)[0])
            for path, (lo, hi) in spec.random.items():
                values[path] = float(rng.uniform(lo, hi))
        values.update(lab_columns(spec, i))
        out.append(Task(i, run_seed, values))
    return out


def load_spec(path: Path) -> CampaignSpec:
    """SPEC.toml, its config path made absolute (SpecError naming the file and field)."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text())
    except OSError as e:
        raise SpecError(f"{path}: cannot read ({e.strerror or e})") from None
    except tomllib.TOMLDecodeError as e:
        raise SpecError(f"{path}: not TOML ({e})") from None
    try:
        spec = CampaignSpec.model_validate(doc)
    except ValidationError as e:
        err = e.errors()[0]
        where = ".".join(str(x) for x in err["loc"]) or "the top"
        raise SpecError(f"{path}: {where}: {err['msg']}") from None
    if spec.config is not None:
        cfg = (path.parent / spec.config).resolve()
        if not cfg.is_file():
            raise SpecError(f"{path}: config: no file {cfg}")
        spec = spec.model_copy(update={"config": str(cfg)})
    return spec
