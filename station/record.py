"""Writing a run's record: every sheet as JSON under DIR/sheets, and DIR/results.json."""

from __future__ import annotations

import json
from pathlib import Path

from procedures.journal import dumps
from procedures.runner import Run


def write_sheets(out: Path, run: Run) -> None:
    (out / "sheets").mkdir(parents=True, exist_ok=True)
    for name, model in run.sheets.items():
        (out / "sheets" / f"{name}.json").write_text(
            json.dumps(json.loads(dumps({"x": model}))["x"], indent=1, sort_keys=True))


def write_results(out: Path, res: dict) -> None:
    (out / "results.json").write_text(json.dumps(res, indent=1, sort_keys=True))
