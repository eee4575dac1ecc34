"""The Monte Carlo bench scripts as thin wrappers over a campaign of bench/campaigns/."""

from __future__ import annotations

import sys
from pathlib import Path

from rich.console import Console

from laboratory.campaign.cli import show
from laboratory.campaign.run import run_campaign
from laboratory.campaign.spec import load_spec
from laboratory.campaign.store import CampaignStore


def run_bench(name: str, argv: list[str]) -> None:
    """``python bench/<x>_mc.py [N] [SEED] [OUT]``: the spec bench/campaigns/<name>.toml
    with N tasks and campaign seed SEED on the machine's cores; the summary on screen, the
    Parquet under OUT (default runs/campaign/bench-<name>-<seed>-<n>, resumed if there)."""
    spec = load_spec(Path(__file__).parent / "campaigns" / f"{name}.toml")
    upd: dict[str, int] = {}
    if len(argv) > 1:
        upd["seeds"] = int(argv[1])
    if len(argv) > 2:
        upd["seed"] = int(argv[2])
    spec = spec.model_copy(update=upd)
    out = Path(argv[3]) if len(argv) > 3 else \
        Path("runs/campaign") / f"bench-{name}-{spec.seed}-{spec.seeds}"
    res = run_campaign(spec, out, resume=(out / "campaign.json").is_file(),
                       console=Console(), quiet=not sys.stderr.isatty())
    show(res.summary)
    tasks = CampaignStore(out).table("tasks")
    inside = res.summary["inside"].dropna()
    print(f"{res.n_tasks} tasks ({res.ran} run now), mean wall time of a task "
          f"{tasks['wall_s'].mean():.2f} s; {int(inside.sum())} of {len(inside)} constants "
          f"inside their 99 % chi-square interval; {res.failed} failed; Parquet in {out}")
