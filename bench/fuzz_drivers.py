"""Fuzz targets of the driver reply parsers: one per driver method that parses a reply,
the ESG data-line checker and ``ProcessorDriver.lines``.

Each input is a reply drawn with the instrument's own format string, mutated (lost,
flipped and inserted bytes, lost decimal point or sign, nan/inf/underscores, extra or lost
fields, extra, stray, split and over-long lines, a cut line) and fed to the driver over a
scripted link (tests/reply_specs.py: the oracle, the link and the mutations). The outcome
is predicted from the oracle; then the same call again with a clean reply must give that
reply's value (a leftover line must never be taken for it).

    python bench/fuzz.py 100000 --only drv.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from fuzz_core import FuzzTarget  # noqa: E402
from reply_specs import SPECS, Spec, run_line_checker, run_lines, run_one  # noqa: E402


def _quiet() -> None:
    """Every dropped line is logged as a warning: a fuzz run drops millions."""
    logging.getLogger("station.drivers").setLevel(logging.ERROR)


def _target(spec: Spec) -> FuzzTarget:
    return FuzzTarget(f"drv.{spec.name}", lambda rng: run_one(spec, rng), setup=_quiet)


TARGETS: list[FuzzTarget] = [
    *(_target(s) for s in SPECS),
    FuzzTarget("drv.esg.LineChecker.check", run_line_checker, setup=_quiet),
    FuzzTarget("drv.ProcessorDriver.lines", run_lines, setup=_quiet),
]
