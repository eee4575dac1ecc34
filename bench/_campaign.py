"""The Monte Carlo bench scripts as thin wrappers over a campaign of bench/campaigns/."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from _args import count
from rich.console import Console

from laboratory.campaign.cli import show
from laboratory.campaign.run import run_campaign
from laboratory.campaign.spec import load_spec
from laboratory.campaign.store import CampaignStore


def run_bench(name: str, argv: list[str], description: str | None = None) -> None:
    """``python bench/<x>_mc.py [N] [SEED] [OUT]``: the spec bench/campaigns/<name>.toml
    with N tasks and campaign seed SEED on the machine's cores; the summary on screen, the
    Parquet under OUT (default runs/campaign/bench-<name>-<seed>-<n>, resumed if there).
    ``argv`` is the whole command line (``sys.argv``: the program's name first);
    ``description`` heads ``--help``."""
    spec_file = Path(__file__).parent / "campaigns" / f"{name}.toml"
    ap = argparse.ArgumentParser(prog=Path(argv[0]).name if argv else None,
                                 description=description)
    ap.add_argument("n", metavar="N", nargs="?", type=count, default=None,
                    help=f"tasks (seeds) of the campaign (default: the spec's, {spec_file.name})")
    ap.add_argument("seed", metavar="SEED", nargs="?", type=int, default=None,
                    help="the campaign seed (default: the spec's)")
    ap.add_argument("out", metavar="OUT", nargs="?", type=Path, default=None,
                    help=f"the campaign's directory, resumed if there (default "
                    f"runs/campaign/bench-{name}-SEED-N)")
    a = ap.parse_args(argv[1:])
    if a.seed is not None and a.seed < 0:
        ap.error(f"SEED must be 0 or more, got {a.seed}")
    spec = load_spec(spec_file)
    upd: dict[str, int] = {}
    if a.n is not None:
        upd["seeds"] = a.n
    if a.seed is not None:
        upd["seed"] = a.seed
    spec = spec.model_copy(update=upd)
    out = a.out if a.out is not None else \
        Path("runs/campaign") / f"bench-{name}-{spec.seed}-{spec.seeds}"
    res = run_campaign(spec, out, resume=(out / "campaign.json").is_file(),
                       console=Console(), quiet=not sys.stderr.isatty())
    show(res.summary)
    tasks = CampaignStore(out).table("tasks")
    inside = res.summary["inside"].dropna()
    print(f"{res.n_tasks} tasks ({res.ran} run now), mean wall time of a task "
          f"{tasks['wall_s'].mean():.2f} s; {int(inside.sum())} of {len(inside)} constants "
          f"inside their 99 % chi-square interval; {res.failed} failed; Parquet in {out}")
