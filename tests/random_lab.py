"""Random admissible laboratories: a re-export of laboratory/isu/random_lab.py (issue 19),
the one generator the tests, the bench scripts and `station campaign` share."""

from __future__ import annotations

import numpy as np

from laboratory.isu.random_lab import ACCEL_COEFS, GYRO_COEFS, random_station
from station.config.isu import default_dict

__all__ = ["ACCEL_COEFS", "GYRO_COEFS", "random_overrides", "random_station"]


def random_overrides(rng: np.random.Generator, *, redraw_isu: bool = True,
                     noise: float | None = None) -> dict:
    """Config overrides of one random laboratory drawn from ``rng`` over the default, its
    ``[plan]`` the manual's standard times whatever the laboratory (random_labs.MANUAL_DAY:
    no requirement lengthens a gate or refuses the day, e.g. for a drawn oscillator's
    offset)."""
    from random_labs import MANUAL_DAY

    from laboratory.isu.random_lab import draw

    over = draw(rng, default_dict(), redraw_isu=redraw_isu, noise=noise).overrides
    return {**over, "plan": MANUAL_DAY.requirements.model_dump(mode="json")}
