"""The calibration history: every finished run indexed in a database (SQLAlchemy; SQLite by
default at runs/history.sqlite), a unit's runs and the trends of its constants."""

from __future__ import annotations

import sys
from pathlib import Path


def index_after(run_dir: Path) -> None:
    """What every run command calls at its end: index the finished run into the history.
    Nothing database-like is imported unless the run is to be indexed; a plain SQLite file
    is written with the stdlib (``lite``), any other URL through SQLAlchemy (``store``). A
    failure is a warning on stderr, never the run's."""
    from laboratory.history.where import _first_line, history_url_for, is_finished

    try:
        if not is_finished(Path(run_dir)):
            return
        url = history_url_for(Path(run_dir))
        if url is None:
            return
        from laboratory.history.lite import index_run_sqlite, sqlite_file

        db = sqlite_file(url)
        if db is not None:
            index_run_sqlite(db, Path(run_dir))
            return
        from laboratory.history.store import index_after as index
    except Exception as e:  # noqa: BLE001 - the run's own outcome must come through
        print(f"warning: {run_dir} not indexed in the history: {_first_line(e)}",
              file=sys.stderr)
        return
    index(run_dir)
