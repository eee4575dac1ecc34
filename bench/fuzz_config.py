"""Fuzz targets for the configuration loaders of the three laboratories (bench/fuzz.py):

    python bench/fuzz.py 10000 --only config

Each input is one document of tests/config_docs.py (a valid document with a few
mutations, sometimes damaged bytes). Outcomes: "rejected" a ConfigError of one line naming
the file (and a field of the laboratory for a validation error); "accepted" a document the
loader took, whose rack was built (and, every fifth, its noise processes run for three
simulated minutes, all finite); "wrong" a rejection without the file or the field, or an
accepted configuration whose rack is not finite. A traceback is an escaped exception.
"""

from __future__ import annotations

import random
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from config_docs import LABS, document, outcome  # noqa: E402
from fuzz_core import FuzzTarget  # noqa: E402

_DIR = Path(tempfile.mkdtemp(prefix="fuzz-config-"))
_count = {lab: 0 for lab in LABS}


def _target(lab: str) -> FuzzTarget:
    def run(rng: random.Random) -> str:
        _count[lab] += 1
        _, raw = document(rng, lab)
        try:
            kind, _ = outcome(lab, raw, _DIR / f"{lab}.toml", seed=rng.randrange(1000),
                              run_noise=_count[lab] % 5 == 0)
        except AssertionError:
            return "wrong"
        return kind

    return FuzzTarget(f"config {lab}", run, setup=_imports)


def _imports() -> None:
    """The racks' modules, imported before the clock runs (seconds the first time)."""
    import station.racks.cigtf  # noqa: F401
    import station.racks.esg  # noqa: F401
    import station.racks.isu  # noqa: F401


TARGETS = [_target(lab) for lab in LABS]
