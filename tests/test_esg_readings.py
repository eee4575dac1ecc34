"""One dividing-head setting's reading (procedures.esg.readings): which pickoffs it keeps,
its journal form, and the failed check when a pickoff the procedure needs is off the
pattern."""

from __future__ import annotations

import json

import pytest

from procedures.esg.readings import Setting, read_setting
from station.drivers.esg import BadLine, DataLine
from station.errors import CheckFailed

PERIOD = 4_000_000  # 100 MHz counts of ten revolutions


class FakeProcessor:
    """Hands out prepared lines, one batch per ``lines`` call (what read_setting asks)."""

    def __init__(self, batches: list[list[DataLine | BadLine]]) -> None:
        self.batches = batches
        self.selected: tuple[int, int] | None = None

    def select(self, a: int, b: int) -> None:
        self.selected = (a, b)

    def lines(self, k: int) -> list[DataLine | BadLine]:
        return self.batches.pop(0)[:k]


def line(t_hr: float, c2: int, c1: int = 0) -> DataLine:
    """A line with pickoff 2's count ``c2`` and pickoff 1's ``c1`` (0: off the pattern)."""
    return DataLine(t_hr, (c1, c2, 0), 1, PERIOD, f"{t_hr} {c1} {c2}")


def test_pickoff_off_the_pattern_is_kept_out_and_named():
    counts = [1_800_000, 1_800_004, 1_799_998, 1_800_002]
    got = [line(1.0 + 0.001 * i, c) for i, c in enumerate(counts)]
    garbled = line(1.0045, 2_600_000)  # a mis-gated count: far from the others
    proc = FakeProcessor([[got[0], garbled, got[1], BadLine("x", "bad checksum"), *got[2:]]])
    s = read_setting(proc, (2, 1), n_lines=6)
    assert proc.selected == (2, 1)
    assert s.cr[1] is None
    assert set(s.line_cr) == {2}
    assert s.line_cr[2] == [c / PERIOD for c in counts]
    assert s.ratio(2) == sum(c / PERIOD for c in counts) / 4
    assert s.t_s == pytest.approx(3600.0 * (1.0 + 0.0015), abs=1e-9)
    assert len(s.rejected) == 2
    assert s.rejected[0].startswith("bad checksum")
    with pytest.raises(CheckFailed, match="pickoff 1 is off the pattern"):
        s.ratio(1)


def test_setting_journal_form_round_trips():
    s = Setting((2, 1), 3605.4, {2: 0.45, 1: None}, [3600.0, 3610.8], {2: [0.45, 0.45]},
                ["bad checksum: 'x'"])
    back = Setting.from_reading(json.loads(json.dumps(s.reading())))
    assert back == s
    assert back.pickoffs == (2, 1)
