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
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, TypeAdapter

from station.hil.links_dir import DirHandle

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
    text = json.dumps(asdict(s), indent=2) + "\n"
    if isinstance(links_dir, DirHandle):
        return links_dir.write_text(FILENAME, text)
    d = DirHandle(Path(links_dir))
    try:
        return d.write_text(FILENAME, text)
    finally:
        d.close()


def read(links_dir: Path) -> Session | None:
    """The session of the rack served under ``links_dir``, or None if there is none."""
    path = Path(links_dir) / FILENAME
    if not path.exists():
        return None
    return Session(**json.loads(path.read_text()))


class StationParams(BaseModel):
    """What the session of a CIGTF or ESG rack digests: the station and its effective
    parameters. Those are dataclasses (CigtfParams, EsgParams), not pydantic models, so they
    are dumped to JSON data first; a client that loads the same ``[cigtf]``/``[esg]`` config
    (``load_cigtf_params``/``load_esg_params``) gets the same params, hence the same digest."""

    model_config = ConfigDict(frozen=True)
    station: str
    params: dict


def params_digest(station: str, params: Any) -> str:
    """``session.config_digest`` of a station's effective params (see StationParams)."""
    data = TypeAdapter(type(params)).dump_python(params, mode="json")
    return config_digest(StationParams(station=station, params=data))
