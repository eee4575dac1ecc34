"""What a served rack tells its clients besides the link map: ``DIR/session.json``.

The session names the server run (so a client can tell a restarted rack from the one it
was talking to), the station it serves, the seed and a digest of the configuration (so a
client can say whether its own config describes the served world, and only then compare
with truth), and the time base: ``speed`` and the ``time.monotonic()`` reading at which
the rack's simulated time was zero. CLOCK_MONOTONIC is shared by the processes of one
machine, so a client's WallClock built from it reads the rack's simulated seconds.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, TypeAdapter

from station.hil.links_dir import DirHandle
from station.hil.links_dir import write_text as links_dir_write

FILENAME = "session.json"


@dataclass(frozen=True)
class Session:
    session: str  # unique per server start
    station: str  # "isu" | "cigtf" | "esg"
    seed: int
    speed: float
    config_digest: str
    t0_monotonic: float  # monotonic wall time at which simulated time 0 was due
    pid: int


def config_digest(cfg: BaseModel) -> str:
    """Digest of a config but its links and rehearsal faults: the same world and truth,
    whatever the wiring."""
    data = cfg.model_dump(mode="json", exclude={"links", "faults"})
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]


def write(links_dir: DirHandle | Path, s: Session) -> Path:
    """Write atomically (a reader never sees half of it), following no symlink."""
    return links_dir_write(links_dir, FILENAME, json.dumps(asdict(s), indent=2) + "\n")


class BadSession(ValueError):
    """``session.json`` is not what a server writes (names the file and the field)."""


_FIELDS = {"session": str, "station": str, "seed": int, "speed": float,
           "config_digest": str, "t0_monotonic": float, "pid": int}


def parse(text: str, where: str = FILENAME) -> Session:
    """A session from the text of ``session.json``; BadSession if anything is off."""
    try:
        data = json.loads(text)
    except ValueError as e:
        raise BadSession(f"{where}: not JSON ({e})") from None
    if not isinstance(data, dict):
        raise BadSession(f"{where}: not a JSON object")
    missing = [k for k in _FIELDS if k not in data]
    extra = [k for k in data if k not in _FIELDS]
    if missing or extra:
        raise BadSession(f"{where}: fields {', '.join(missing)} missing" if missing else
                         f"{where}: unknown fields {', '.join(extra)}")
    out: dict[str, Any] = {}
    for key, kind in _FIELDS.items():
        v = data[key]
        ok = (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
              if kind is float else isinstance(v, kind) and not isinstance(v, bool))
        if not ok:
            raise BadSession(f"{where}: {key} must be {kind.__name__}, got {v!r:.40}")
        out[key] = float(v) if kind is float else v
    if not out["speed"] > 0 or out["pid"] <= 0:
        raise BadSession(f"{where}: speed and pid must be positive")
    return Session(**out)


def read(links_dir: Path) -> Session | None:
    """The session of the rack served under ``links_dir``, or None if there is none;
    BadSession if the file is not a server's."""
    path = Path(links_dir) / FILENAME
    try:
        text = path.read_text()
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as e:
        raise BadSession(f"{path}: cannot read: {e}") from None
    return parse(text, str(path))


class StationParams(BaseModel):
    """What the session of a CIGTF or ESG rack digests: the station and its effective
    parameters. Those are dataclasses (CigtfParams, EsgParams), not pydantic models, so they
    are dumped to JSON data first; a client that loads the same ``[cigtf]``/``[esg]`` config
    (``load_cigtf_params``/``load_esg_params``) gets the same params, hence the same digest."""

    model_config = ConfigDict(defer_build=True, frozen=True)
    station: str
    params: dict


def params_digest(station: str, params: Any) -> str:
    """``session.config_digest`` of a station's effective params (see StationParams)."""
    data = TypeAdapter(type(params)).dump_python(params, mode="json")
    return config_digest(StationParams(station=station, params=data))
