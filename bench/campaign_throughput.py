"""Campaign throughput: whole calibration days per minute on 1 and 2 LocalCluster workers,
in process for reference, and the round trip Dask adds to a task (a no-op's).

    python bench/campaign_throughput.py [DAYS] [COMMAND_SPEC]   (default 4, campaigns/day.toml)

Prints figures only (no assertion): the machine's other load moves them.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from _args import count, parser

from laboratory.campaign.run import dask_client, run_campaign
from laboratory.campaign.spec import load_spec
from laboratory.campaign.store import CampaignStore
from laboratory.campaign.task import noop


def overhead(n: int = 200) -> None:
    """Per-task round trip of a no-op on a 2-worker LocalCluster: one at a time, and all
    submitted at once (what a campaign does)."""
    with dask_client(None, 2) as client:
        client.submit(noop, -1, pure=False).result()  # warm
        t = time.perf_counter()
        for i in range(n):
            client.submit(noop, i, pure=False).result()
        one = (time.perf_counter() - t) / n
        t = time.perf_counter()
        client.gather(client.map(noop, range(n), pure=False))
        many = (time.perf_counter() - t) / n
    print(f"no-op task round trip: {1e3 * one:.2f} ms one at a time, {1e3 * many:.2f} ms "
          f"per task when {n} are submitted together")


def main(argv: list[str] | None = None) -> None:
    ap = parser(__doc__)
    ap.add_argument("days", metavar="DAYS", nargs="?", type=count, default=4,
                    help="tasks of each campaign (default 4)")
    ap.add_argument("spec_file", metavar="COMMAND_SPEC", nargs="?", type=Path,
                    default=Path(__file__).parent / "campaigns" / "day.toml",
                    help="the campaign spec whose command runs (default bench/campaigns/day.toml)")
    a = ap.parse_args(argv)
    if not a.spec_file.is_file():
        ap.error(f"COMMAND_SPEC {a.spec_file} is not a file")
    days, spec_file = a.days, a.spec_file
    spec = load_spec(spec_file).model_copy(update={"seeds": days, "grid": {}, "random": {}})
    overhead()
    for workers in (0, 1, 2):
        with tempfile.TemporaryDirectory() as d:
            t = time.perf_counter()
            res = run_campaign(spec, Path(d) / "c", workers=workers)
            wall = time.perf_counter() - t
            tasks = CampaignStore(Path(d) / "c").table("tasks")
        where = "in process" if workers == 0 else f"{workers} worker(s)"
        print(f"{spec.command} x {days} on {where}: {wall:.1f} s with cluster start, "
              f"{60 * days / wall:.2f} per minute; mean task {tasks['wall_s'].mean():.1f} s; "
              f"failed {res.failed}", flush=True)


if __name__ == "__main__":
    main()
