"""A long counter gate costs what a short one does (issue 17): on a still table the running
integral computes half an hour of cells in the batch that opens the gate, so a 30-minute
gate needs no batch of physics of its own, and the readings are those of one cell per batch."""

from __future__ import annotations

import pytest

from sim.isu import integrator
from station.config.isu import load_config
from station.racks.isu import SimulatedRack, open_isu_drivers


def gate(seconds: float, seed: int) -> tuple[int, int]:
    """(reading, integrand batches while the gate ran) of one measure X-Y gate of string
    A1S1 against OSC1, on a fresh rack with the table set and still."""
    cfg = load_config(seed=seed)
    rack = SimulatedRack(cfg)
    st = open_isu_drivers(cfg, rack)
    try:
        for ax, deg in zip((1, 2, 3, 4), (0.0, 90.0, 0.0, 0.0), strict=True):
            st.table.move(ax, deg)
        st.table.wait_still()
        ci = rack.world.integral
        calls = []
        inner = ci._integrand
        ci._integrand = lambda t, mid: (calls.append(t.size), inner(t, mid))[1]
        st.patch_panel.connect("A1S1", 1, "X")
        st.patch_panel.connect("OSC1", 1, "Z")
        st.counters[1].set_mode("measure X-Y")
        st.counters[1].set_preset(int(seconds * 20000))
        st.counters[1].operate()
        reading = int(st.counters[1].read(timeout=seconds * 2 + 10))
        return reading, len(calls)
    finally:
        st.close()
        rack.close()


@pytest.mark.parametrize("seed", [2, 9])
def test_long_gate_needs_no_batch_of_its_own(seed):
    _, short = gate(1.0, seed)
    _, long = gate(1800.0, seed)
    assert short == long == 1


@pytest.mark.parametrize("seconds", [1.0, 1800.0])
def test_readings_do_not_depend_on_the_lookahead(seconds, monkeypatch):
    """The same clock count with half an hour of cells ahead as with one cell per batch."""
    ahead, _ = gate(seconds, 4)
    monkeypatch.setattr(integrator, "LOOKAHEAD", 0)
    one_by_one, batches = gate(seconds, 4)
    assert ahead == one_by_one
    assert batches == (1 if seconds < 60 else 2)
