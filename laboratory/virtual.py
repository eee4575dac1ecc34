"""A laboratory's virtual station and its run functions, for tests and campaigns.

``virtual_station`` loads any registered laboratory's config with a seed and dotted-path
overrides (pydantic configs and the dataclass params of the CIGTF and ESG laboratories
alike); ``PROCEDURES`` runs a command's run function into a directory; ``read_record`` reads
the record it leaves. The pytest plugin (``laboratory.pytest_plugin``) and ``station
campaign`` (``laboratory.campaign``) both use these; this module imports no pytest, so a Dask
worker needs none.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from laboratory import registry


def _set(doc: Any, path: str, value: Any) -> None:
    """Set the dotted ``path`` (list items by index: ``isu.accels.0.D0_g``) in ``doc``."""
    parts = path.split(".")
    node = doc
    for i, p in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            if not p.isdigit() or int(p) >= len(node):
                raise KeyError(f"config override {path!r}: no item {p!r} at "
                               f"{'.'.join(parts[:i]) or 'the top'}")
            key: Any = int(p)
        elif isinstance(node, dict):
            if p not in node:
                raise KeyError(f"config override {path!r}: no field {p!r} at "
                               f"{'.'.join(parts[:i]) or 'the top'}")
            key = p
        else:
            raise KeyError(f"config override {path!r}: {'.'.join(parts[:i])} is a value")
        if last:
            node[key] = value
        else:
            node[key] = list(node[key]) if isinstance(node[key], tuple) else node[key]
            node = node[key]


def replaced(obj: Any, path: str, value: Any) -> Any:
    """A frozen dataclass with the dotted ``path`` set (ValueError naming an unknown field);
    the dataclass validates the new value as its constructor does."""
    head, _, rest = path.partition(".")
    if not dataclasses.is_dataclass(obj) or head not in {f.name for f in dataclasses.fields(obj)}:
        raise ValueError(f"config override {path!r}: no field {head!r} in "
                         f"{type(obj).__name__}")
    new = replaced(getattr(obj, head), rest, value) if rest else value
    return dataclasses.replace(obj, **{head: new})  # type: ignore[type-var]


def override(model: Any, overrides: Mapping[str, Any]) -> Any:
    """A config with dotted-path overrides: a pydantic model validated again (a bad value
    fails as the config reader's models refuse it), or a frozen dataclass rebuilt."""
    if not overrides:
        return model
    if dataclasses.is_dataclass(model):
        for path, value in overrides.items():
            model = replaced(model, path, value)
        return model
    doc = model.model_dump()
    for path, value in overrides.items():
        _set(doc, path, value)
    return type(model).model_validate(doc)


@dataclass(frozen=True)
class VirtualStation:
    """A laboratory's virtual station: its registry entry and its loaded config (seed and
    overrides applied)."""

    lab: registry.Laboratory
    cfg: Any
    overrides: Mapping[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.lab.name

    @property
    def seed(self) -> int:
        return self.lab.seed_of(self.cfg)

    def truth(self) -> dict[str, float]:
        """The simulator's true values of what this laboratory estimates."""
        return self.lab.truth(self.cfg)


def virtual_station(name: str = "isu", seed: int | None = None,
                    overrides: Mapping[str, Any] | None = None,
                    config: Path | None = None) -> VirtualStation:
    """The virtual station of laboratory ``name``: its config (``config`` file or the
    default) with ``seed`` and the dotted-path ``overrides`` (e.g. ``isu.accels.0.D0_g``;
    for CIGTF and ESG paths inside their params, e.g. ``latitude_deg``)."""
    lab = registry.get(name)
    cfg = lab.load_config(config, seed)
    over = dict(overrides or {})
    if over:
        if hasattr(cfg, "params"):  # a Seeded laboratory: the overrides are its params'
            from laboratory.seeded import Seeded

            cfg = Seeded(override(cfg.params, over), cfg.seed)
        else:
            cfg = override(cfg, over)
    return VirtualStation(lab, cfg, over)


@dataclass(frozen=True)
class Record:
    """A finished run's record as its files hold it."""

    dir: Path
    run: dict[str, Any]  # run.json
    results: dict[str, Any]  # results.json, gyrocompass.json or esg.json
    sheets: dict[str, Any]  # sheets/<name>.json by name
    returned: dict[str, Any]  # what the run function returned

    def row(self, instrument: str, parameter: str) -> dict[str, Any]:
        """The Chart II-5 row of one constant (KeyError naming it)."""
        for r in self.results.get("calibration") or ():
            if (r["instrument"], r["parameter"]) == (instrument, parameter):
                return dict(r)
        raise KeyError(f"no result row {instrument}.{parameter} in {self.dir}")


def _quiet() -> Any:
    from rich.console import Console

    return Console(quiet=True)


def _day(st: VirtualStation, out: Path, options: dict[str, Any]) -> dict[str, Any]:
    from laboratory.isu.day import DayRequest, run_day

    return run_day(DayRequest(st.cfg, out, **{"quiet": True, **options}), _quiet())


def _align(st: VirtualStation, out: Path, options: dict[str, Any]) -> dict[str, Any]:
    from laboratory.isu.align import AlignRequest, run_align

    return run_align(AlignRequest(st.cfg, out, **{"quiet": True, **options}), _quiet())


def _gyrocompass(st: VirtualStation, out: Path, options: dict[str, Any]) -> dict[str, Any]:
    from laboratory.cigtf.gyrocompassing import run_gyrocompass_test

    return run_gyrocompass_test(st.cfg.seed, out, st.cfg.params, **options)


def _esg(st: VirtualStation, out: Path, options: dict[str, Any]) -> dict[str, Any]:
    from laboratory.esg.calibration import run_esg_calibration

    return run_esg_calibration(st.cfg.seed, out, st.cfg.params, **options)


Runner = Callable[[VirtualStation, Path, dict[str, Any]], dict[str, Any]]
# command -> (its laboratory, its run function); a laboratory's suite may add its own
PROCEDURES: dict[str, tuple[str, Runner]] = {
    "day": ("isu", _day),
    "align": ("isu", _align),
    "gyrocompass-test": ("cigtf", _gyrocompass),
    "esg-calibration": ("esg", _esg),
}
RESULT_FILES = ("results.json", "gyrocompass.json", "esg.json")


def read_record(d: Path, returned: dict[str, Any] | None = None) -> Record:
    """The record in run directory ``d``."""
    d = Path(d)
    results: dict[str, Any] = {}
    for name in RESULT_FILES:
        if (d / name).is_file():
            results = json.loads((d / name).read_text())
            break
    sheets = {f.stem: json.loads(f.read_text()) for f in sorted((d / "sheets").glob("*.json"))}
    run = json.loads((d / "run.json").read_text()) if (d / "run.json").is_file() else {}
    return Record(d, run, results, sheets, returned or {})
