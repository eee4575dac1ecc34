"""Property: no configuration document makes a loader raise anything but a ConfigError,
every rejection is one line naming the file (and the field), and every accepted
configuration builds its rack, whose noise processes stay finite for a few simulated
minutes. Documents: tests/config_docs.py; bench/fuzz_config.py runs tens of thousands."""

from __future__ import annotations

import random

import pytest
from config_docs import document, outcome
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

EXAMPLES = {"ISU": 100, "CIGTF": 100, "ESG": 40}  # a few seconds each


@pytest.mark.parametrize("lab", sorted(EXAMPLES))
def test_mutated_documents_are_refused_cleanly_or_run(lab, tmp_path_factory):
    path = tmp_path_factory.mktemp(f"fuzz-{lab}") / "c.toml"

    @settings(max_examples=EXAMPLES[lab], deadline=None,
              suppress_health_check=[HealthCheck.too_slow])
    @given(st.integers(0, 2**64 - 1))
    def check(seed: int) -> None:
        rng = random.Random(seed)
        _, raw = document(rng, lab)
        outcome(lab, raw, path, seed=seed % 1000)  # raises on a traceback or a bad message

    check()


@given(st.binary(max_size=300))
@settings(max_examples=100, deadline=None)
def test_random_bytes(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("bytes") / "c.toml"
    for lab in ("ISU", "CIGTF", "ESG"):
        outcome(lab, data, path, run_noise=False)


@given(st.text(alphabet=st.characters(codec="utf-8"), max_size=200))
@settings(max_examples=60, deadline=None)
def test_random_text(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("text") / "c.toml"
    for lab in ("ISU", "CIGTF", "ESG"):
        outcome(lab, text.encode("utf-8", "surrogatepass"), path, run_noise=False)
