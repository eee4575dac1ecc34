"""The run's identity (run.json) and its resolved configuration (config.toml), written when
a run starts and closed when it ends, as Bluesky's start and stop documents are.

``identified`` wraps a run's journaled part: it writes config.toml and run.json with status
"running", and rewrites run.json at the end: "completed", "stopped" (a StopError: chart,
step and the one-line reason) or "aborted" (an interrupt or any other escaping exception:
its class and message). A resumed run keeps its run_uid (from run.json, else from the
journal's start note) and its start; only the end is rewritten.
"""

from __future__ import annotations

import datetime as dt
import getpass
import hashlib
import json
import math
import os
import re
import sys
import uuid
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Annotated, Any

import typer

from laboratory import vcs
from station.errors import OperatorError, StopError
from station.files import write_bytes

RUN_JSON = "run.json"
CONFIG_TOML = "config.toml"
# run.json's run-specific stamps: two runs of the same seed and config differ only in these
# (argv too: it names each run's own --out)
STAMPS = ("run_uid", "started_utc", "ended_utc", "vcs_revision", "argv")


@dataclass(frozen=True)
class Invocation:
    """Who ran the command and how: the operator (None: the environment's) and argv."""

    operator: str | None = None
    argv: tuple[str, ...] = ()
    identity: Any = None  # a CIGTF or ESG file's [identity] (None: the defaults)


_INVOCATION: ContextVar[Invocation | None] = ContextVar("invocation", default=None)


@contextmanager
def invoked(operator: str | None, argv: list[str] | None = None, identity: Any = None
            ) -> Iterator[None]:
    """Runs inside are the command line's: ``--operator``, ``argv`` (default sys.argv) and
    the config file's ``[identity]`` (CIGTF, ESG)."""
    token = _INVOCATION.set(Invocation(operator, tuple(sys.argv if argv is None else argv),
                                       identity))
    try:
        yield
    finally:
        _INVOCATION.reset(token)


OperatorOpt = Annotated[str | None, typer.Option(
    "--operator", help="the principal operator on the record and the sheets (default: "
    "$STATION_OPERATOR, else the login name)")]


def operator_name(given: str | None = None) -> str:
    """``--operator``, else $STATION_OPERATOR, else the login name, else "unknown"."""
    for name in (given, os.environ.get("STATION_OPERATOR")):
        if name and name.strip():
            return " ".join(name.split())
    try:
        login = getpass.getuser()
    except Exception:  # noqa: BLE001 - no login name is no reason to fail a run
        login = ""
    return login or "unknown"


def vcs_revision(tree: Path = vcs.SOURCE_TREE) -> str | None:
    """``git rev-parse HEAD`` of the source tree (``-dirty`` with changes), None when the
    package does not run from a git checkout; never an error (laboratory.vcs)."""
    return vcs.revision(tree)


def package_version() -> str:
    """The installed package's version, else the source tree's."""
    try:
        return metadata.version("isu-station")
    except metadata.PackageNotFoundError:
        import station

        return station.__version__


# ----------------------------------------------------------------------------- TOML


_BARE = re.compile(r"[A-Za-z0-9_-]+")


def _key(k: object) -> str:
    s = str(k)
    return s if _BARE.fullmatch(s) else json.dumps(s)


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"{v!r} has no place in a configuration")
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)  # JSON's escapes are TOML basic-string escapes
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()
                               if x is not None) + "}"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def _is_table_array(v: Any) -> bool:
    return isinstance(v, (list, tuple)) and bool(v) and all(isinstance(x, Mapping) for x in v)


def to_toml(doc: Mapping[str, Any]) -> str:
    """A document (JSON-like; None values left out) as TOML: scalars and arrays first,
    then each table, arrays of tables as ``[[...]]``."""
    lines: list[str] = []

    def table(d: Mapping[str, Any], path: list[str]) -> None:
        for k, v in d.items():
            if v is None or isinstance(v, Mapping) or _is_table_array(v):
                continue
            lines.append(f"{_key(k)} = {_value(v)}")
        for k, v in d.items():
            if isinstance(v, Mapping):
                lines.append("")
                lines.append("[" + ".".join(_key(p) for p in (*path, k)) + "]")
                table(v, [*path, k])
            elif _is_table_array(v):
                for x in v:
                    lines.append("")
                    lines.append("[[" + ".".join(_key(p) for p in (*path, k)) + "]]")
                    table(x, [*path, k])

    table(doc, [])
    return "\n".join(lines).lstrip("\n") + "\n"


# ----------------------------------------------------------------------------- the run


@dataclass
class RunIdentity:
    """The identity of one run: ``record`` is run.json's content; ``verdict`` the overall
    outcome once judged (set by the run before it ends)."""

    out: Path
    record: dict[str, Any]

    @property
    def run_uid(self) -> str:
        return str(self.record["run_uid"])

    @property
    def verdict(self) -> str | None:
        return self.record.get("verdict")

    @verdict.setter
    def verdict(self, value: str | None) -> None:
        self.record["verdict"] = value

    def header(self, experiment: str, identification: str | None = None,
               special_procedures: str | None = None) -> dict[str, Any]:
        """A sheet heading (procedures.sheets.SheetHeader without sheets_used) from the
        identity: the date is the run's UTC start date."""
        unit = self.record["unit"]
        return {"experiment": experiment,
                "principal_operator": self.record["operator"],
                "date": str(self.record["started_utc"])[:10],
                "identification": identification or next(iter(unit.values()), ""),
                "special_procedures": special_procedures}

    def write(self) -> None:
        """run.json (laboratory.record is imported here: it brings the procedures, which a
        command line that only starts or shows its help does not need)."""
        from laboratory.record import write_json

        write_json(self.out / RUN_JSON, self.record)


def _now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")


def previous_uid(out: Path, journal_records: list[dict]) -> tuple[str | None, dict]:
    """The run_uid of the run being resumed in ``out`` and its run.json (or {}): run.json
    first, else the journal's first start note."""
    try:
        old = json.loads((out / RUN_JSON).read_bytes())
        if isinstance(old, dict) and isinstance(old.get("run_uid"), str):
            return old["run_uid"], old
    except (OSError, ValueError):
        pass
    for r in journal_records:
        if r.get("event") == "start" and isinstance(r.get("run_uid"), str):
            return r["run_uid"], {}
    return None, {}


def end_of(e: BaseException | None) -> dict[str, Any]:
    """run.json's closing fields for a run that ended with ``e`` (None: normally)."""
    if e is None:
        return {"status": "completed", "reason": None, "chart": None, "step": None,
                "exit_code": 0}
    line = " ".join(str(e).split()) or type(e).__name__
    if isinstance(e, OperatorError) and e.exit_code == 3:  # a FAILED verdict: it completed
        return {"status": "completed", "reason": line, "chart": None, "step": None,
                "exit_code": 3}
    if isinstance(e, StopError):
        step = getattr(e, "step", None)
        return {"status": "stopped", "reason": line, "chart": getattr(e, "chart", None),
                "step": None if step is None else str(step), "exit_code": e.exit_code}
    code = e.exit_code if isinstance(e, OperatorError) else (
        130 if isinstance(e, KeyboardInterrupt) else 1)
    return {"status": "aborted", "reason": f"{type(e).__name__}: {line}", "chart": None,
            "step": None, "exit_code": code}


@contextmanager
def identified(out: Path, laboratory: str, command: str, seed: int, config: Mapping[str, Any],
               station_id: str, unit: Mapping[str, str], resume: bool = False,
               journal_records: list[dict] | None = None) -> Iterator[RunIdentity]:
    """config.toml and run.json (status "running") written in ``out``, run.json closed
    however the block ends (the exception goes on). ``config``: the resolved configuration
    as a document."""
    out = Path(out)
    inv = _INVOCATION.get() or Invocation()
    text = to_toml(config).encode("utf-8")
    uid, old = previous_uid(out, journal_records or []) if resume else (None, {})
    record: dict[str, Any] = {
        "run_uid": uid or uuid.uuid4().hex, "laboratory": laboratory, "command": command,
        "argv": list(inv.argv), "started_utc": old.get("started_utc") or _now(), "ended_utc": None,
        "version": package_version(), "vcs_revision": vcs_revision(), "seed": seed,
        "config_file": CONFIG_TOML, "config_digest": hashlib.sha256(text).hexdigest(),
        "station_id": station_id, "unit": dict(unit),
        "operator": old.get("operator") or operator_name(inv.operator),
        "status": "running", "reason": None, "chart": None, "step": None,
        "verdict": None, "exit_code": None,
    }
    write_bytes(out / CONFIG_TOML, text)
    ident = RunIdentity(out, record)
    ident.write()
    token = _CURRENT.set(ident)
    try:
        yield ident
    except BaseException as e:
        _close(ident, e)
        raise
    finally:
        _CURRENT.reset(token)
    _close(ident, None)


_CURRENT: ContextVar[RunIdentity | None] = ContextVar("run_identity", default=None)


def current() -> RunIdentity | None:
    """The identity of the run in progress (None outside one): where a verdict is set."""
    return _CURRENT.get()


@dataclass(frozen=True)
class Identifying:
    """What ``identified`` needs of a CIGTF or ESG run (journaled_run's ``identify``)."""

    laboratory: str
    command: str
    seed: int
    section: str
    model: type[Any]  # the section's config model (CigtfConfig, EsgConfig)
    params: Any
    # sub-tables of the section the params do not hold (the ESG's [esg.procedure]: the
    # settings the run used), written over the ones read from the params
    tables: dict[str, dict[str, Any]] = field(default_factory=dict)

    def config(self) -> tuple[dict[str, Any], str, dict[str, str]]:
        """The resolved config document, station_id and unit serials."""
        from station.config.identity import load_identity

        inv = _INVOCATION.get() or Invocation()
        ident = inv.identity or load_identity(None, self.section.upper())
        doc = section_config(self.section, self.model, self.params, ident)
        doc[self.section].update(self.tables)
        return doc, ident.station_id, ident.unit.model_dump()


def _close(ident: RunIdentity, e: BaseException | None) -> None:
    end = end_of(e)
    if e is None and ident.verdict == "FAIL":  # completed, but a limit failed: exit 3
        end.update(reason="verdict: FAIL", exit_code=3)
    ident.record.update(end, ended_utc=_now())
    try:
        ident.write()
    except OSError:
        if e is None:
            raise


# ----------------------------------------------------------------------------- configs


def isu_config(cfg: Any) -> dict[str, Any]:
    """The ISU StationConfig as a document load_config reads back to the same config
    (faults: only what was set, as their validators expect)."""
    doc = cfg.model_dump(mode="json", exclude_none=True)
    doc["faults"] = {k: v.model_dump(mode="json", exclude_unset=True)
                     for k, v in cfg.faults.items()}
    return doc


def isu_identity(cfg: Any) -> tuple[str, dict[str, str]]:
    """station_id and unit serials of an ISU StationConfig."""
    return cfg.identity.station_id, cfg.identity.unit.model_dump()


def section_config(section: str, model: type[Any], params: Any, identity: Any) -> dict[str, Any]:
    """A CIGTF or ESG run's params as its ``[section]`` (each field of the section's
    ``model`` read from ``params`` or its sub-dataclasses) with ``[identity]``."""
    def pick(m: type[Any], *sources: Any) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for name, f in m.model_fields.items():
            sub = f.annotation if isinstance(f.annotation, type) else None
            if sub is not None and hasattr(sub, "model_fields"):
                out[name] = pick(sub, *(getattr(s, name) for s in sources if hasattr(s, name)))
                continue
            for s in sources:
                if hasattr(s, name):
                    out[name] = getattr(s, name)
                    break
        return out

    sources = [params] + [getattr(params, n) for n in ("rotor",) if hasattr(params, n)]
    return {section: pick(model, *sources), "identity": identity.model_dump(mode="json")}
