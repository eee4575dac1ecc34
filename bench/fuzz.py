"""Fuzz every parser of the station and print, per parser, inputs, escaped exceptions,
hangs and malformed inputs accepted as values.

    python bench/fuzz.py [N] [--seed S] [--only SUBSTRING]

N inputs per parser (default 100,000). Targets come from the ``bench/fuzz_<area>.py``
modules (``TARGETS``); see bench/fuzz_core.py for the classification. Exit 1 if any
parser let an exception escape, hung or accepted a malformed input.
"""

from __future__ import annotations

import importlib
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from _args import count, parser  # noqa: E402
from fuzz_core import FuzzTarget, run_target  # noqa: E402


def targets() -> list[FuzzTarget]:
    out: list[FuzzTarget] = []
    for path in sorted(HERE.glob("fuzz_*.py")):
        if path.stem == "fuzz_core":
            continue
        out += importlib.import_module(path.stem).TARGETS
    return out


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("n", metavar="N", nargs="?", type=count, default=100_000,
                    help="inputs per parser (default 100000)")
    ap.add_argument("--seed", metavar="S", type=int, default=1, help="(default 1)")
    ap.add_argument("--only", metavar="SUBSTRING", default="",
                    help="only the parsers whose name contains this")
    args = ap.parse_args(argv)
    bad = 0
    for t in targets():
        if args.only not in t.name:
            continue
        w0 = time.perf_counter()
        rep = run_target(t, args.n, args.seed)
        print(f"{rep.line()}  ({time.perf_counter() - w0:.1f} s)", flush=True)
        for k, v in rep.examples.items():
            print(f"    first {k}: {v}")
        bad += sum(rep.escaped.values()) + rep.hangs + rep.kinds["wrong"]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
