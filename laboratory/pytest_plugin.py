"""The station's pytest plugin: fixtures for a laboratory's own test suite.

Installed with the package (entry point ``pytest11``: ``station``), it gives any test
``station_lab`` (a virtual station of any registered laboratory: its name, seed and config
overrides), ``run_procedure`` (runs one of the laboratory's commands into the test's
``tmp_path`` and returns its record: results, sheets, run.json) and the assertion
``assert_within_sigma`` (a value within k sigma of the truth or of a baseline). See
docs/regression.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from laboratory.virtual import (
    PROCEDURES,
    Record,
    VirtualStation,
    override,
    read_record,
    virtual_station,
)

__all__ = ["PROCEDURES", "Record", "VirtualStation", "assert_within_sigma", "override",
           "read_record", "run_procedure", "station_lab", "virtual_station", "within_sigma"]


def assert_within_sigma(value: float, truth_or_baseline: float, sigma: float, k: float = 4.0,
                        name: str = "value") -> float:
    """Assert |value - reference| <= k sigma; returns z. The failure names the value, its z
    and the reference, so a suite's report reads as a calibration sheet."""
    if value is None or truth_or_baseline is None:
        raise AssertionError(f"{name}: no value to hold ({value!r} against "
                             f"{truth_or_baseline!r})")
    if sigma is None or not sigma > 0 or not math.isfinite(sigma):
        raise AssertionError(f"{name}: sigma must be a positive number, got {sigma!r}")
    z = (value - truth_or_baseline) / sigma
    if not abs(z) <= k:
        raise AssertionError(f"{name} = {value:.8g} is {z:+.2f} sigma from {truth_or_baseline:.8g} "
                             f"(sigma {sigma:.3g}; allowed {k:g})")
    return z


@pytest.fixture
def station_lab() -> Callable[..., VirtualStation]:
    """``station_lab(name="isu", seed=None, overrides=None, config=None)``: a virtual
    station of any registered laboratory."""
    return virtual_station


@pytest.fixture
def run_procedure(tmp_path: Path) -> Callable[..., Record]:
    """``run_procedure(command, station=None, out=None, **options)``: run the command's run
    function (``day``, ``align``, ``gyrocompass-test``, ``esg-calibration``) on ``station``
    (default: its laboratory's default virtual station) into a fresh directory under the
    test's tmp_path, and return its record."""
    count = [0]

    def run(command: str, station: VirtualStation | None = None, out: Path | None = None,
            **options: Any) -> Record:
        if command not in PROCEDURES:
            raise KeyError(f"run_procedure: unknown command {command!r} (known: "
                           f"{', '.join(PROCEDURES)})")
        lab, fn = PROCEDURES[command]
        st = station if station is not None else virtual_station(lab)
        if st.name != lab:
            raise ValueError(f"run_procedure: {command} is the {lab} laboratory's command, "
                             f"the station given is {st.name}'s")
        count[0] += 1
        d = out if out is not None else tmp_path / f"{command}-{count[0]}"
        return read_record(d, fn(st, d, dict(options)))

    return run


@pytest.fixture
def within_sigma() -> Callable[..., float]:
    """``assert_within_sigma`` as a fixture, for suites that take helpers as fixtures."""
    return assert_within_sigma
