"""A campaign's directory: its spec and one Parquet part per finished task.

``campaign.json`` (the spec, its digest, the number of tasks), ``rows/`` (one row per task
and constant), ``failures/`` (a failed task's one-line message), ``tasks/`` (one row per
finished task: status, wall time, worker). Each part is written whole (a temporary name,
then renamed) as its task completes, the ``tasks/`` part last: a task is done when its
``tasks/`` part exists, so an interrupted client resumes from exactly the tasks stored.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import pandas as pd

from laboratory.campaign.spec import CampaignSpec, SpecError

TABLES = ("rows", "failures", "tasks")


class CampaignStore:
    """The campaign directory ``out``."""

    def __init__(self, out: Path) -> None:
        self.out = Path(out)

    @property
    def meta_file(self) -> Path:
        return self.out / "campaign.json"

    def open(self, spec: CampaignSpec, resume: bool) -> set[int]:
        """Make (or, resuming, check) the directory for ``spec``; the indices already done.
        A directory that holds another campaign, or one without ``resume``, is refused."""
        if self.meta_file.is_file():
            if not resume:
                raise SpecError(f"--out {self.out}: already holds a campaign (--resume to "
                                "continue it)")
            meta = json.loads(self.meta_file.read_text())
            if meta.get("digest") != spec.digest():
                raise SpecError(f"--resume {self.out}: the campaign there was started from "
                                "another spec (digest differs)")
            return self.done()
        if resume:
            raise SpecError(f"--resume: {self.out} holds no campaign (no campaign.json)")
        if self.out.exists() and any(self.out.iterdir()):
            raise SpecError(f"--out {self.out}: not empty")
        for t in TABLES:
            (self.out / t).mkdir(parents=True, exist_ok=True)
        self._write_text(self.meta_file, json.dumps(
            {"spec": spec.document(), "digest": spec.digest(),
             "n_tasks": spec.n_tasks(), "sweep": spec.sweep_paths()}, indent=1))
        return set()

    def done(self) -> set[int]:
        """The indices of the tasks stored."""
        return {int(p.stem.split("-")[1]) for p in (self.out / "tasks").glob("part-*.parquet")}

    @staticmethod
    def _write_text(path: Path, text: str) -> None:
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(text)
        os.replace(tmp, path)

    def _write(self, table: str, index: int, df: pd.DataFrame) -> None:
        path = self.out / table / f"part-{index:06d}.parquet"
        tmp = path.with_name(path.name + ".tmp")
        df.to_parquet(tmp, index=False)
        os.replace(tmp, path)

    def put(self, result: dict[str, Any], sweep: list[str]) -> None:
        """Store one task's result (``laboratory.campaign.task.run_task``), tasks part last."""
        i = result["index"]
        head = {"task": i, "seed": result["seed"],
                **{p: result["values"].get(p) for p in sweep}}
        if result["rows"]:
            self._write("rows", i, pd.DataFrame(
                [{**head, "row": k, **r} for k, r in enumerate(result["rows"])]))
        if result["failure"] is not None:
            self._write("failures", i, pd.DataFrame([{**head, "message": result["failure"]}]))
        self._write("tasks", i, pd.DataFrame([{
            **head, "status": "failed" if result["failure"] is not None else "ok",
            "n_rows": len(result["rows"]), "wall_s": float(result["wall_s"]),
            "worker": result["worker"]}]))

    def table(self, name: str) -> pd.DataFrame:
        """One table, every part, in task order (an empty frame when none)."""
        parts = sorted((self.out / name).glob("part-*.parquet"))
        if not parts:
            return pd.DataFrame()
        df = pd.concat([pd.read_parquet(p) for p in parts], ignore_index=True)
        keys = ["task", "row"] if "row" in df.columns else ["task"]
        return df.sort_values(keys, kind="stable").reset_index(drop=True)
