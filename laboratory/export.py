"""Standard exports of a run's record: result rows as CSV, the raw IEU samples of every
alignment as CSV, and every IEU frame of a run as a python-can ASC log in simulated time.

Written atomically beside the JSON record (``station.files``); the JSON stays the record,
these are copies in formats other tools read (spreadsheets, python-can, cantools).
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from station.files import atomic_path, write_bytes

if TYPE_CHECKING:  # python-can and the IEU's driver are the ISU's: imported by can_log
    from station.drivers.isu.ieu import IeuDriver

CAN_LOG = "ieu.asc"
SAMPLES_DIR = "alignments"


# the exact types most cells hold (an alignment's samples), written after one lookup
_PLAIN: dict[type, Callable[[Any], str]] = {float: float.__repr__, int: int.__repr__, str: str}


def csv_cell(v: Any) -> str:
    """A value as a CSV cell: empty for None, repr for floats (exact round trip), JSON for
    lists and dicts."""
    plain = _PLAIN.get(type(v))
    if plain is not None:
        return plain(v)
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):  # numpy's float64 too: its repr is "np.float64(x)"
        return repr(float(v))
    if isinstance(v, (list, tuple, dict)):
        return json.dumps(v, sort_keys=True)
    return str(v)


def csv_text(rows: Iterable[dict]) -> str:
    """The rows as CSV text: a header of every key in order of first appearance, one line
    per row."""
    rows = list(rows)
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(keys)
    for r in rows:
        w.writerow([csv_cell(r.get(k)) for k in keys])
    return buf.getvalue()


def write_csv(path: Path, rows: Iterable[dict]) -> None:
    """``path`` holds the rows as CSV, atomically."""
    write_bytes(Path(path), csv_text(rows).encode("utf-8"))


def write_results_csv(out: Path, rows: list[dict], name: str = "results.csv") -> None:
    """DIR/results.csv (or ``name``): the result rows of results.json, row for row."""
    write_csv(Path(out) / name, rows)


def write_alignment_samples(out: Path, outcomes: Iterable[Any]) -> list[Path]:
    """DIR/alignments/<method>-<estimator>-ieu.csv for every alignment that sampled the
    IEU (an ``Outcome`` whose detail holds ``ieu_samples``); the paths written."""
    written = []
    texts: dict[int, tuple[Any, bytes]] = {}  # id: (samples, CSV) of each record written
    for o in outcomes:
        raw = getattr(o, "detail", {}).get("ieu_samples")
        if raw is None:
            continue
        d = Path(out) / SAMPLES_DIR
        d.mkdir(parents=True, exist_ok=True)
        path = d / f"{o.method}-{o.estimator}-ieu.csv"
        if id(raw) not in texts:  # two techniques of one method share their record
            texts[id(raw)] = (raw, csv_text(raw.rows()).encode("utf-8"))
        write_bytes(path, texts[id(raw)][1])
        written.append(path)
    return written


@contextmanager
def can_log(out: Path, ieu: IeuDriver) -> Iterator[Path]:
    """Log every IEU frame (both directions) to DIR/ieu.asc through python-can's ASC writer
    while the block runs. Times are the frames' simulated (virtual) seconds, absolute: the
    log's time origin is the simulation's. The log is kept if the block raises (a stopped
    run)."""
    import can

    path = Path(out) / CAN_LOG
    raised: BaseException | None = None
    with atomic_path(path) as tmp:
        # the writer can.Logger picks for a .asc file, made directly: Logger first scans
        # every installed package's metadata for writer plug-ins (3-5 ms a run, issue 17)
        writer = can.ASCWriter(tmp)
        writer.log_event("station: times are simulated seconds", 0.0)  # time origin t = 0
        ieu.frame_hook = writer.on_message_received
        try:
            yield path
        except BaseException as e:  # noqa: BLE001  # kept, re-raised once the log is closed
            raised = e
        finally:
            ieu.frame_hook = None
            writer.stop()
    if raised is not None:
        raise raised
