"""The toy laboratory's world: a bath at a true temperature drawn from the seed."""

from __future__ import annotations

from dataclasses import dataclass

import simpy

from sim.rng import stream


@dataclass(frozen=True)
class ToyParams:
    noise_k: float = 0.05  # one reading's noise, K (1 sigma)


class BathWorld:
    def __init__(self, seed: int, params: ToyParams | None = None,
                 env: simpy.Environment | None = None) -> None:
        self.p = params or ToyParams()
        self.env = env if env is not None else simpy.Environment()
        self.true_k = 273.15 + float(stream(seed, "toy.bath").uniform(15.0, 35.0))
        self._noise = stream(seed, "toy.noise")

    def reading_k(self) -> float:
        return self.true_k + self.p.noise_k * float(self._noise.standard_normal())
