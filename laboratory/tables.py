"""Console tables that never cut a number: a table too wide for the console is printed as
several narrower ones (the key columns repeated in each), and a cell that still does not
fit wraps (``fold``) instead of ending in an ellipsis. rich is imported when a
table is made: a quiet run prints none (issue 17)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text


@dataclass(frozen=True)
class Column:
    name: str
    right: bool = True  # numbers right-justified, names left


def _table(title: str | None, cols: Sequence[Column], rows: Sequence[Sequence[str | Text]],
           idx: Sequence[int]) -> Table:
    from rich import box
    from rich.table import Table

    t = Table(title=title, box=box.SIMPLE_HEAD, pad_edge=False, collapse_padding=True)
    for i in idx:
        c = cols[i]
        t.add_column(c.name, justify="right" if c.right else "left", overflow="fold")
    for r in rows:
        t.add_row(*(r[i] for i in idx))
    return t


def fits(console: Console, table: Table) -> bool:
    """The table's natural width (unwrapped cells) fits the console."""
    return _width(console, table) <= console.width


def print_fitted(console: Console, title: str, cols: Sequence[Column],
                 rows: Sequence[Sequence[str | Text]], keys: int = 2) -> None:
    """One table if it fits the console; otherwise the first ``keys`` columns with as many
    of the others as fit, repeated until every column is shown (titles say which part).
    A cell is markup, parsed once here (rich would parse it at each measure and render)."""
    from rich.text import Text

    cells: list[list[str | Text]] = [[Text.from_markup(c) if isinstance(c, str) else c
                                      for c in r] for r in rows]
    widths = column_widths(console, cols, cells)
    key_idx = list(range(keys))
    if table_width(widths) <= console.width:
        console.print(_table(title, cols, cells, range(len(cols))))
        return
    parts: list[list[int]] = []
    cur: list[int] = []
    for i in range(keys, len(cols)):
        if cur and table_width([widths[j] for j in key_idx + cur + [i]]) > console.width:
            parts.append(cur)
            cur = []
        cur.append(i)
    parts.append(cur)
    for n, part in enumerate(parts, 1):
        console.print(_table(f"{title} ({n}/{len(parts)})", cols, cells, key_idx + part))


def column_widths(console: Console, cols: Sequence[Column],
                  rows: Sequence[Sequence[str | Text]]) -> list[int]:
    """Each column's natural width, header and cells unwrapped (markup rendered), measured
    once per cell: a table of any of these columns is then as wide as ``table_width`` says."""
    from rich.cells import cell_len
    from rich.measure import Measurement
    from rich.text import Text

    options = console.options.update_width(10_000)
    widths = [Measurement.get(console, options, c.name).maximum for c in cols]
    for r in rows:
        for i, cell in enumerate(r):
            w = (max(cell_len(line) for line in cell.plain.split("\n"))
                 if isinstance(cell, Text) else Measurement.get(console, options, cell).maximum)
            widths[i] = max(widths[i], w)
    return widths


def table_width(widths: Sequence[int]) -> int:
    """The natural width of a ``_table`` of columns this wide: the two edges, a divider and
    a one-space pad between neighbours (``collapse_padding``, no pad at the edges)."""
    return sum(widths) + 2 * len(widths)


def _width(console: Console, table: Table) -> int:
    """The table's natural width: its cells unwrapped, on a console wide enough."""
    from rich.measure import Measurement

    return Measurement.get(console, console.options.update_width(10_000), table).maximum
