"""``NAME=TEXT`` items of the command line (``--require``, ``--times``, ``--vary``)."""

from __future__ import annotations

from collections.abc import Collection


def named_item(option: str, item: str, names: Collection[str], usage: str) -> tuple[str, str]:
    """(NAME, TEXT) of ``item``, NAME one of ``names``; ValueError ``OPTION 'ITEM': USAGE``
    when there is no ``=`` or the name is not one of them."""
    name, eq, text = item.partition("=")
    name = name.strip()
    if not eq or name not in names:
        raise ValueError(f"{option} {item!r}: {usage}")
    return name, text
