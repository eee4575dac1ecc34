"""laboratory.tables: the widths computed from each column measured once are the widths rich
measures for the table, so a split table never runs past the console and shows every cell."""

from __future__ import annotations

import io
import random

import pytest
from rich.cells import cell_len
from rich.console import Console
from rich.text import Text

from laboratory.tables import Column, _table, _width, column_widths, print_fitted, table_width

CELLS = ["-", "1.2345678e-05", "[red]+4.56[/]", "[dim]not determined[/]", "ünï", "宽字符",
         "a b c", "[bold]FAIL[/]", "0.98765432"]


def _random_table(rng: random.Random) -> tuple[list[Column], list[list[str]]]:
    n = rng.randint(1, 10)
    cols = [Column(rng.choice(["inst", "param", "estimate", "err/sig", "数", "x" * 14]),
                   rng.random() < 0.5) for _ in range(n)]
    rows = [[rng.choice(CELLS + ["y" * rng.randint(0, 40)]) for _ in range(n)]
            for _ in range(rng.randint(0, 8))]
    return cols, rows


@pytest.mark.parametrize("seed", range(5))
def test_table_width_is_what_rich_measures(seed: int) -> None:
    rng = random.Random(seed)
    checked = 0
    for _ in range(60):
        cols, rows = _random_table(rng)
        con = Console(file=io.StringIO(), width=80)
        widths = column_widths(con, cols, rows)
        for _ in range(3):
            idx = sorted(rng.sample(range(len(cols)), rng.randint(1, len(cols))))
            assert table_width([widths[i] for i in idx]) == _width(
                con, _table(None, cols, rows, idx)), (cols, rows, idx)
            checked += 1
    assert checked == 180


@pytest.mark.parametrize("seed", range(5))
def test_split_tables_fit_and_show_every_cell(seed: int) -> None:
    rng = random.Random(100 + seed)
    fitted = 0
    for _ in range(20):
        cols, rows = _random_table(rng)
        width = rng.randint(40, 160)
        buf = io.StringIO()
        con = Console(file=buf, width=width, color_system=None)
        print_fitted(con, "T", cols, rows, keys=min(2, len(cols)))
        text = buf.getvalue()
        lines = text.splitlines()
        key_w = table_width(column_widths(con, cols[:2], [r[:2] for r in rows]))
        widest = max(column_widths(con, cols, rows)) + 2
        assert "\u2026" not in text  # a cell too wide folds onto more lines, never cut
        if key_w + widest > width:
            continue
        fitted += 1  # every part fits: no line past the console, every cell whole
        assert max(cell_len(line) for line in lines) <= width
        plain = Console(file=io.StringIO(), width=10_000)
        for r in rows:
            for cell in r:
                for word in plain.render_str(cell).plain.split():
                    assert word in text, (cell, width)
    assert fitted >= 5


@pytest.mark.parametrize("seed", range(4))
def test_markup_parsed_once_prints_as_rich_prints_it(seed: int) -> None:
    """print_fitted parses each cell's markup once (issue 17); measured and printed, the
    parsed cells come out as rich makes the markup strings, plain or in colour."""
    rng = random.Random(300 + seed)
    for _ in range(25):
        cols, rows = _random_table(rng)
        parsed = [[Text.from_markup(c) for c in r] for r in rows]
        width = rng.randint(30, 160)
        for terminal in (False, True):
            outs = []
            for cells in (rows, parsed):
                buf = io.StringIO()
                con = Console(file=buf, width=width, force_terminal=terminal,
                              color_system="truecolor" if terminal else None)
                outs.append((column_widths(con, cols, cells), buf))
                con.print(_table("T", cols, cells, range(len(cols))))
            (w_str, b_str), (w_text, b_text) = outs
            assert w_str == w_text
            assert b_str.getvalue() == b_text.getvalue()
