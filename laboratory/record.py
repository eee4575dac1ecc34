"""Writing a run's record: every file atomically (``station.files``), every name inside
the run directory. Sheets go to DIR/sheets/<name>.json under plain names only.
"""

from __future__ import annotations

import json
import os
import pickle
from pathlib import Path
from typing import Any

from procedures.journal import dumps, is_safe_name
from procedures.runner import Run
from station.files import clear_prefixed, fsync_dir, write_bytes


def json_bytes(obj: Any) -> bytes:
    """A JSON file's content as the record writes it (indented, sorted keys)."""
    return json.dumps(obj, indent=1, sort_keys=True).encode("utf-8")


def write_json(path: Path, obj: Any, sync_dir: bool = True) -> None:
    """A JSON file of the record (``json_bytes``), atomically."""
    write_bytes(path, json_bytes(obj), sync_dir)


def sheet_path(out: Path, name: str) -> Path:
    """DIR/sheets/<name>.json; ValueError for a name that is not a plain file name."""
    if not is_safe_name(name):
        raise ValueError(f"sheet name {name!r} is not a plain file name: it would address a "
                         "path outside the run directory")
    return Path(out) / "sheets" / f"{name}.json"


def sheet_value(model: Any) -> Any:
    """A sheet as its JSON value (its journal form)."""
    return json.loads(dumps({"x": model}))["x"]


def sheet_values(run: Run) -> dict[str, Any]:
    """Every sheet of ``run`` as its JSON value, by name; the names are checked where they
    become paths (``write_sheet_values``)."""
    return {name: sheet_value(model) for name, model in run.sheets.items()}


def write_sheet_values(out: Path, values: dict[str, Any]) -> None:
    """``values`` (name: JSON value) as DIR/sheets/<name>.json, each atomically; one
    directory sync at the end. A pure writer of its arguments: the day hands it to its
    plot child when that is idle (issue 17)."""
    paths = {name: sheet_path(out, name) for name in values}
    (Path(out) / "sheets").mkdir(parents=True, exist_ok=True)
    for name, value in values.items():
        write_json(paths[name], value, sync_dir=False)
    fsync_dir(Path(out) / "sheets")


# Sheets carried to the plot child as their models pickled (a tenth of the cost of their
# JSON values here) and rendered there: those of the calibration while the alignments run,
# the rest at the end (issue 17). In the child, each rendered file is staged, synced, as
# DIR/.sheets-stage.<name>.json with the pickle it came from; a sheet pickled the same at
# the end is renamed into sheets/ from there. A run that stops first leaves stages, which
# the day clears (``clear_prefixed(out, SHEET_STAGE)``) once its plot child has ended.
Blobs = dict[str, bytes]  # sheet name: its model pickled
SHEET_STAGE = ".sheets-stage."
_rendered: dict[str, tuple[bytes, Path]] = {}  # name: (pickle, its staged file) made here


def sheet_blobs(sheets: dict[str, Any]) -> Blobs | None:
    """Each of ``sheets`` (name: model, as ``Run.sheets``) pickled, by name (None: a sheet
    pickle cannot carry)."""
    try:
        return {name: pickle.dumps(model, protocol=pickle.HIGHEST_PROTOCOL)
                for name, model in sheets.items()}
    except (pickle.PicklingError, TypeError, AttributeError):
        return None


def _sheet_file(blob: bytes) -> bytes:
    """The file of the sheet pickled in ``blob``, as ``write_sheet_values`` writes it."""
    return json_bytes(sheet_value(pickle.loads(blob)))  # noqa: S301 - our own pickle


def render_sheet_blobs(out: Path, blobs: Blobs) -> None:
    """Render the sheets' files now (in the plot child, while the run goes on) and stage
    each, synced, beside the record for ``write_sheet_blobs``; nothing in sheets/."""
    for name, blob in blobs.items():
        sheet_path(out, name)  # a name that is no plain file name: refused before a file
        staged = Path(out) / f"{SHEET_STAGE}{name}.json"
        write_bytes(staged, _sheet_file(blob), sync_dir=False)
        _rendered[name] = (blob, staged)


def write_sheet_blobs(out: Path, blobs: Blobs) -> None:
    """``blobs`` as DIR/sheets/<name>.json, each atomically, one directory sync at the end:
    the files ``write_sheet_values`` writes of the same sheets. A sheet staged before from
    the same pickle is renamed into place; the stages left are removed."""
    paths = {name: sheet_path(out, name) for name in blobs}
    (Path(out) / "sheets").mkdir(parents=True, exist_ok=True)
    for name, blob in blobs.items():
        held = _rendered.pop(name, None)
        if held is not None and held[0] == blob and held[1].is_file():
            os.replace(held[1], paths[name])
        else:
            write_bytes(paths[name], _sheet_file(blob), sync_dir=False)
    fsync_dir(Path(out) / "sheets")
    clear_prefixed(Path(out), SHEET_STAGE)


def write_sheets(out: Path, run: Run) -> None:
    """Every sheet of ``run`` as DIR/sheets/<name>.json (each atomically; one directory
    sync at the end)."""
    write_sheet_values(out, sheet_values(run))


def write_results(out: Path, res: dict) -> None:
    """DIR/results.json, atomically."""
    write_json(Path(out) / "results.json", res)
