"""The bench scripts' command lines: one parser shape, and argument types that refuse a count
below 1 or a length not above 0 with argparse's one-line error (exit 2)."""

from __future__ import annotations

import argparse
from typing import Any


def parser(doc: str | None, **kw: Any) -> argparse.ArgumentParser:
    """A script's parser, its ``--help`` headed by the first paragraph of ``doc``."""
    return argparse.ArgumentParser(description=(doc or "").split("\n\n")[0] or None, **kw)


def count(text: str) -> int:
    """A whole number of 1 or more (seeds, days, jobs)."""
    n = int(text)  # not a number: argparse says "invalid count value"
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be 1 or more, got {n}")
    return n


def positive(text: str) -> float:
    """A number above 0 (hours, a speed, a timeout)."""
    x = float(text)
    if not x > 0:
        raise argparse.ArgumentTypeError(f"must be above 0, got {text}")
    return x


def seeds(ap: argparse.ArgumentParser, n: int, first: int) -> None:
    """The Monte Carlo scripts' positional N (seeds, default ``n``) and first_seed."""
    ap.add_argument("n", metavar="N", nargs="?", type=count, default=n,
                    help=f"seeds (default {n})")
    ap.add_argument("first", metavar="first_seed", nargs="?", type=int, default=first,
                    help=f"the first seed (default {first})")
