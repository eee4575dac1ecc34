"""The calibration history: every finished run indexed in a database (SQLAlchemy; SQLite by
default at runs/history.sqlite), a unit's runs and the trends of its constants."""

from __future__ import annotations

import sys
from pathlib import Path


def index_after(run_dir: Path) -> None:
    """What every run command calls at its end: index the finished run into the history
    (SQLAlchemy imported only then). A failure is a warning on stderr, never the run's."""
    try:
        from laboratory.history.store import index_after as index
    except Exception as e:  # noqa: BLE001 - the run's own outcome must come through
        print(f"warning: {run_dir} not indexed in the history: {e}", file=sys.stderr)
        return
    index(run_dir)
