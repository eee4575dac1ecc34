"""Console tables that never cut a number: a table too wide for the console is printed as
several narrower ones (the key columns repeated in each), and a cell that still does not
fit wraps (``fold``) instead of ending in an ellipsis."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from rich import box
from rich.console import Console
from rich.measure import Measurement
from rich.table import Table


@dataclass(frozen=True)
class Column:
    name: str
    right: bool = True  # numbers right-justified, names left


def _table(title: str | None, cols: Sequence[Column], rows: Sequence[Sequence[str]],
           idx: Sequence[int]) -> Table:
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
                 rows: Sequence[Sequence[str]], keys: int = 2) -> None:
    """One table if it fits the console; otherwise the first ``keys`` columns with as many
    of the others as fit, repeated until every column is shown (titles say which part)."""
    everything = list(range(len(cols)))
    whole = _table(title, cols, rows, everything)
    if fits(console, whole):
        console.print(whole)
        return
    key_idx = list(range(keys))
    parts = _parts_by_widths(console, cols, rows, key_idx, everything[keys:])
    if parts is None:  # the widths did not add up: measure each trial table as it grows
        parts = _parts_by_trials(console, cols, rows, key_idx, everything[keys:])
    for n, part in enumerate(parts, 1):
        console.print(_table(f"{title} ({n}/{len(parts)})", cols, rows, key_idx + part))


def _width(console: Console, table: Table) -> int:
    """The table's natural width: its cells unwrapped, on a console wide enough."""
    return Measurement.get(console, console.options.update_width(10_000), table).maximum


def _parts_by_trials(console: Console, cols: Sequence[Column], rows: Sequence[Sequence[str]],
                     key_idx: list[int], rest: list[int]) -> list[list[int]]:
    """The parts by measuring key columns + the part so far + the next column each time."""
    parts: list[list[int]] = []
    cur: list[int] = []
    for i in rest:
        trial = _table(None, cols, rows, key_idx + cur + [i])
        if cur and not fits(console, trial):
            parts.append(cur)
            cur = []
        cur.append(i)
    if cur:
        parts.append(cur)
    return parts


def _parts_by_widths(console: Console, cols: Sequence[Column], rows: Sequence[Sequence[str]],
                     key_idx: list[int], rest: list[int]) -> list[list[int]] | None:
    """The same parts from each column's width measured once (a table's natural width is
    the key columns' plus each added column's); None when a part's real width disagrees."""
    if not rest:
        return []
    base = _width(console, _table(None, cols, rows, key_idx))
    extra = {i: _width(console, _table(None, cols, rows, key_idx + [i])) - base for i in rest}
    parts: list[list[int]] = []
    cur: list[int] = []
    width = base
    for i in rest:
        if cur and width + extra[i] > console.width:
            parts.append(cur)
            cur, width = [], base
        cur.append(i)
        width += extra[i]
    parts.append(cur)
    for part in parts:  # the sum is the width, or fall back to measuring every trial
        real = _width(console, _table(None, cols, rows, key_idx + part))
        if real != base + sum(extra[i] for i in part):
            return None
    return parts
