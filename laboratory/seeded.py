"""A laboratory config that does not carry its seed (CIGTF, ESG): the params and the seed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Generic, TypeVar

P = TypeVar("P")
DEFAULT_SEED = 1  # the CIGTF and ESG commands' default seed


@dataclass(frozen=True)
class Seeded(Generic[P]):
    params: P
    seed: int


def seeded(params: P, seed: int | None) -> Seeded[P]:
    return Seeded(params, DEFAULT_SEED if seed is None else int(seed))
