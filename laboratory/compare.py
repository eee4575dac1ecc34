"""`station compare DIR_A DIR_B`: which sheet and result values differ between two runs.

The regression-test use of the product: the same procedure, seed and config must give the
same record; a code change shows here as the list of values it moved. The record is every
sheet and the results file of each laboratory (results.json, gyrocompass.json, esg.json);
wall-clock fields are ignored, and so are run.json's run-specific stamps (run uid, start
and end times, VCS revision, argv) and the sheets' header dates.
"""

from __future__ import annotations

import json
from pathlib import Path

from rich.console import Console
from rich.table import Table
from rich.text import Text

from laboratory.tables import fits

IGNORED = {"wall", "wall_seconds", "t_wall"}
# run-specific stamps (laboratory.identity.STAMPS) and a sheet header's date, by path
IGNORED_PATHS = {*(f"run.{k}" for k in ("run_uid", "started_utc", "ended_utc",
                                       "vcs_revision", "argv"))}


def _ignored(path: str) -> bool:
    return path in IGNORED_PATHS or (path.startswith("sheets/") and path.endswith(".header.date"))


def _flatten(x: object, prefix: str, out: dict) -> None:
    if isinstance(x, dict):
        for k, v in x.items():
            path = f"{prefix}.{k}" if prefix else str(k)
            if k in IGNORED or _ignored(path):
                continue
            _flatten(v, path, out)
    elif isinstance(x, list):
        for i, v in enumerate(x):
            key = _row_key(v, i)
            _flatten(v, f"{prefix}[{key}]", out)
    else:
        out[prefix] = x


def _row_key(v: object, i: int) -> str:
    if isinstance(v, dict) and "instrument" in v and "parameter" in v:
        return f"{v['instrument']}:{v['parameter']}"
    return str(i)


RESULT_FILES = ("results.json", "gyrocompass.json", "esg.json", "run.json")


def _read_json(f: Path) -> object:
    try:
        return json.loads(f.read_bytes())
    except OSError as e:
        raise ValueError(f"{f}: cannot read it ({e.strerror})") from None
    except (ValueError, RecursionError) as e:
        raise ValueError(f"{f}: not JSON ({one_line(e)})") from None


def one_line(e: BaseException) -> str:
    return " ".join(str(e).split())


def load_record(d: Path) -> dict:
    """The results files and sheets of a run directory (keyed by file name without .json)."""
    d = Path(d)
    if not d.is_dir():
        raise FileNotFoundError(f"{d}: no such run directory")
    rec: dict = {}
    for name in RESULT_FILES:
        f = d / name
        if f.is_file():
            rec[f.stem if name != "results.json" else "results"] = _read_json(f)
    sheets = d / "sheets"
    if sheets.is_dir():
        for f in sorted(sheets.glob("*.json")):
            rec[f"sheets/{f.stem}"] = _read_json(f)
    if not rec:
        raise FileNotFoundError(f"{d} holds no results ({', '.join(RESULT_FILES)}) and no "
                                "sheets/")
    return rec


def differences(a: Path, b: Path, rel_tol: float = 0.0) -> list[tuple[str, object, object]]:
    fa: dict = {}
    fb: dict = {}
    _flatten(load_record(a), "", fa)
    _flatten(load_record(b), "", fb)
    out = []
    for k in sorted(set(fa) | set(fb)):
        va, vb = fa.get(k, "<absent>"), fb.get(k, "<absent>")
        if va == vb:
            continue
        if (
            rel_tol > 0
            and isinstance(va, (int, float))
            and isinstance(vb, (int, float))
            and abs(va - vb) <= rel_tol * max(abs(va), abs(vb))
        ):
            continue
        out.append((k, va, vb))
    return out


def render_differences(console: Console, diffs: list[tuple[str, object, object]], a: Path,
                       b: Path) -> None:
    """The differences as a table when it fits the console, else one block per value (key,
    then each run's value on its own line): never a key or value cut short, never read as
    markup (keys hold brackets)."""
    cols = ("where", str(a), str(b))
    t = Table(title=Text(f"{len(diffs)} values differ"))
    for c in cols:
        t.add_column(Text(c), overflow="fold")
    for k, va, vb in diffs:
        t.add_row(Text(k), Text(str(va)), Text(str(vb)))
    if fits(console, t):
        console.print(t)
        return
    console.print(f"{len(diffs)} values differ (A: {a}, B: {b})", markup=False,
                  highlight=False, soft_wrap=True)
    for k, va, vb in diffs:
        console.print(k, markup=False, highlight=False, soft_wrap=True)
        console.print(f"  A: {va}", markup=False, highlight=False, soft_wrap=True)
        console.print(f"  B: {vb}", markup=False, highlight=False, soft_wrap=True)
