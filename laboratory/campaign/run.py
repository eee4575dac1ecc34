"""Running a campaign: its missing tasks on Dask (or in process), each stored as it ends.

By default an embedded ``distributed.LocalCluster`` of worker processes (one thread each:
a task is pure Python under the GIL) on the machine's cores; with ``scheduler`` the client
joins an existing cluster (``dask scheduler`` / ``dask worker``, dask-jobqueue, Kubernetes:
docs/campaigns.md), the same code. ``workers=0`` runs the tasks one after another in this
process (no Dask): the reference a cluster's rows must equal. Dask reruns a task whose
worker was lost; ``retries`` more attempts cover a task that raised outside the laboratory
(a refusal or stop is the task's own failure row, not retried).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from laboratory.campaign.spec import CampaignSpec, Task, tasks
from laboratory.campaign.store import CampaignStore
from laboratory.campaign.summary import summarise, write_summary
from laboratory.campaign.task import run_task


@dataclass(frozen=True)
class Outcome:
    """What a campaign call did: tasks in the campaign, run now, already stored, failed."""

    out: Path
    n_tasks: int
    ran: int
    stored_before: int
    failed: int
    summary: pd.DataFrame


@contextmanager
def dask_client(scheduler: str | None, workers: int | None) -> Iterator[Any]:
    """A client on ``scheduler``, or on an embedded LocalCluster of ``workers`` processes
    (None: one per core), closed at the end."""
    from distributed import Client, LocalCluster

    if scheduler is not None:
        client = Client(scheduler, timeout="30s")
        try:
            yield client
        finally:
            client.close()
        return
    n = workers or os.cpu_count() or 1
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                      dashboard_address=None, silence_logs=logging.ERROR) as cluster, \
            Client(cluster) as client:
        yield client


def _results(spec: CampaignSpec, todo: list[Task], scheduler: str | None,
             workers: int | None, retries: int) -> Iterator[dict[str, Any]]:
    """Each task's result as it completes (any order)."""
    if workers == 0 and scheduler is None:
        for t in todo:
            yield run_task(spec, t)
        return
    from distributed import as_completed

    with dask_client(scheduler, workers) as client:
        futures = {client.submit(run_task, spec, t, key=f"campaign-{spec.digest()}-{t.index}",
                                 retries=retries): t for t in todo}
        for fut, res in as_completed(futures, with_results=True, raise_errors=False):
            if isinstance(res, BaseException):  # lost too many workers, or could not run
                t = futures[fut]
                from laboratory.app import one_line

                res = {"index": t.index, "seed": t.seed, "values": dict(t.values),
                       "rows": [], "failure": f"{type(res).__name__}: {one_line(res)}",
                       "wall_s": 0.0, "worker": ""}
            yield res


def run_campaign(spec: CampaignSpec, out: Path, *, scheduler: str | None = None,
                 workers: int | None = None, resume: bool = False, retries: int = 2,
                 console: Console | None = None, quiet: bool = True,
                 on_stored: Callable[[dict[str, Any]], None] | None = None) -> Outcome:
    """Run the campaign ``spec`` into ``out`` (resuming: only the tasks not stored there),
    then write its summary. ``on_stored`` is called after each task is stored."""
    store = CampaignStore(out)
    done = store.open(spec, resume)
    todo = [t for t in tasks(spec) if t.index not in done]
    sweep = spec.sweep_paths()
    failed = 0
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), TimeRemainingColumn(), console=console,
                  disable=quiet) as progress:
        bar = progress.add_task(f"{spec.command} tasks", total=spec.n_tasks(),
                                completed=len(done))
        for res in _results(spec, todo, scheduler, workers, retries):
            store.put(res, sweep)
            failed += res["failure"] is not None
            progress.advance(bar)
            if on_stored is not None:
                on_stored(res)
    summary = summarise(store.table("rows"), list(spec.grid))
    failures = store.table("failures")
    write_summary(store.out, summary, failures, {
        "command": spec.command, "n_tasks": spec.n_tasks(),
        "stored": len(store.done()), "failed": 0 if failures.empty else len(failures)})
    return Outcome(store.out, spec.n_tasks(), len(todo), len(done), failed, summary)
