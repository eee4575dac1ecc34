"""Alignment Parameter Evaluation Sheet (Chart I-8) and the "tape" of M and b (Chart I-7).

The parameter evaluation (Part I, Section 3) is run ahead of an alignment; its output, M and
b of the posterior-mean estimator, goes "on tape" together with the sheet that names the
inputs it was computed from and the reel identification (Chart I-7, step 5). Before an
alignment uses a tape, the operator checks that the sheet's parameters are the experiment's
(III-2.3); ``check_tape`` is that check.

Here the tape is a JSON file: the sheet (identification and every input of Chart I-9, in SI
units, see ``procedures.isu.alignment.estimation``), M (3 x 3K), b (3) and the predicted error
covariance A^-1 (3 x 3).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Literal, TypeGuard

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from procedures.isu.alignment.estimation import LevelParams, posterior_level
from station.files import write_bytes

TAPE_FORMAT: Literal["isu-station alignment tape 1"] = "isu-station alignment tape 1"
REL_TOL = 1e-9  # parameters equal up to float round-off
SCALAR_ABS_TOL = 1e-18
SEQUENCE_ABS_TOL = 1e-12  # times the largest magnitude in the sequence
PRIOR_FRACTION = 0.25  # of sigma_theta and sigma_g: how far T1 and g~ may move (check_tape)


class AlignmentParameterSheet(BaseModel):
    """Chart I-8: the identification of the tape and the inputs of Chart I-9."""

    model_config = ConfigDict(defer_build=True, extra="forbid", frozen=True, allow_inf_nan=False)

    reel_id: str = Field(min_length=1, description="tape (reel) identification, Chart I-7 step 5")
    prepared_by: str = ""
    date: str = ""
    prior_source: str = Field(
        "", description="how T1 was obtained (autocollimators, resolvers, quick alignment)"
    )
    comments: str = ""
    params: LevelParams


class Tape(BaseModel):
    """The sheet with the outputs of the parameter evaluation: M, b and A^-1."""

    model_config = ConfigDict(defer_build=True, extra="forbid", frozen=True, allow_inf_nan=False)

    format: Literal["isu-station alignment tape 1"] = TAPE_FORMAT
    sheet: AlignmentParameterSheet
    M: list[list[float]]
    b: list[float]
    covariance: list[list[float]] = Field(description="A^-1, error covariance, (m/s^2)^2")
    filed_by: str | None = Field(None, description="the run that filed it in a tape library")

    @model_validator(mode="after")
    def _shapes(self) -> Tape:
        K = self.sheet.params.K
        if np.shape(self.M) != (3, 3 * K):
            raise ValueError(f"M must be 3 x {3 * K} for K = {K}, got {np.shape(self.M)}")
        if np.shape(self.b) != (3,) or np.shape(self.covariance) != (3, 3):
            raise ValueError("b must have 3 components and the covariance be 3 x 3")
        return self

    @property
    def params(self) -> LevelParams:
        return self.sheet.params

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(M, b, A^-1) as numpy arrays."""
        return np.asarray(self.M), np.asarray(self.b), np.asarray(self.covariance)


def make_tape(sheet: AlignmentParameterSheet) -> Tape:
    """Run the parameter evaluation (Charts I-9, I-10) for ``sheet`` (Chart I-7, step 4)."""
    M, b, cov = posterior_level(sheet.params)
    return Tape(sheet=sheet, M=M.tolist(), b=b.tolist(), covariance=cov.tolist())


def write_tape(tape: Tape, path: str | Path) -> Path:
    """The tape as a JSON file, written whole or not at all (a kill leaves no half reel)."""
    path = Path(path)
    write_bytes(path, tape.model_dump_json(indent=1).encode("utf-8"))
    return path


def read_tape(path: str | Path) -> Tape:
    return Tape.model_validate_json(Path(path).read_text())


# ---------------------------------------------------------------------------------------------
# The operator's check (III-2.3)
# ---------------------------------------------------------------------------------------------
def check_tape(tape: Tape, expected_params: LevelParams | AlignmentParameterSheet) -> None:
    """Raise ValueError naming the first parameter of the tape's sheet that differs from the
    experiment's (both values given).

    K, Delta t, eps_t, sigma_g, sigma_theta and the noise tables must be equal up to float
    round-off. The nominal T1 and g~ are priors, not settings: a survey repeated on the next
    day moves them by its own noise (a few arcsec), which I-3 does not count as a change of
    parameter. They match when T1 is within PRIOR_FRACTION of sigma_theta (the rotation
    between the two T1) and g~ within PRIOR_FRACTION of sigma_g: the tape's prior is then
    still right to within 3 % of its stated sigma (sqrt(1 + 0.25^2) = 1.03).
    """
    expected = (
        expected_params.params
        if isinstance(expected_params, AlignmentParameterSheet)
        else expected_params
    )
    got = tape.sheet.params
    for field in type(got).model_fields:
        if field not in ("T1", "g_tilde"):
            _compare(field, getattr(got, field), getattr(expected, field))
    dg = abs(got.g_tilde - expected.g_tilde)
    if dg > PRIOR_FRACTION * expected.sigma_g:
        raise ValueError(
            f"tape parameter g_tilde differs from the experiment's by {dg:.3g} m/s^2 (at most "
            f"{PRIOR_FRACTION * expected.sigma_g:.3g}, {PRIOR_FRACTION:g} of sigma_g): tape "
            f"{_fmt(got.g_tilde)}, experiment {_fmt(expected.g_tilde)}")
    angle = t1_angle_rad(got.t1, expected.t1)
    if angle > PRIOR_FRACTION * expected.sigma_theta:
        arcsec = math.degrees(1.0) * 3600.0
        raise ValueError(
            f"tape parameter T1 differs from the experiment's by {angle * arcsec:.1f} arcsec "
            f"(at most {PRIOR_FRACTION * expected.sigma_theta * arcsec:.1f} arcsec, "
            f"{PRIOR_FRACTION:g} of sigma_theta)")


def t1_angle_rad(a: np.ndarray, b: np.ndarray) -> float:
    """The angle of the rotation between two attitudes (rad)."""
    c = (float(np.trace(np.asarray(a).T @ np.asarray(b))) - 1.0) / 2.0
    return math.acos(max(-1.0, min(1.0, c)))


def _fmt(x: object) -> str:
    return repr(x) if not isinstance(x, float) else f"{x:.17g}"


def _differs(name: str, tape_value: object, expected: object) -> ValueError:
    return ValueError(
        f"tape parameter {name} differs from the experiment's: "
        f"tape {_fmt(tape_value)}, experiment {_fmt(expected)}"
    )


def _is_number(x: object) -> TypeGuard[int | float]:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _all_numbers(xs: Sequence[object]) -> bool:
    """Every entry a number (``_is_number``); the types of a tape's long noise tables are
    checked in one pass first (plain floats and ints: 11,520 entries a day, issue 17)."""
    return set(map(type, xs)) <= {float, int} or all(_is_number(x) for x in xs)


def _compare(name: str, a: object, b: object) -> None:
    if isinstance(a, BaseModel) and isinstance(b, BaseModel):
        for field in type(a).model_fields:
            _compare(f"{name}.{field}" if name else field, getattr(a, field), getattr(b, field))
        return
    if isinstance(a, tuple | list) and isinstance(b, tuple | list):
        _compare_sequence(name, a, b)
        return
    if _is_number(a) and _is_number(b):
        if isinstance(a, int) and isinstance(b, int):
            if a != b:
                raise _differs(name, a, b)
        elif not math.isclose(a, b, rel_tol=REL_TOL, abs_tol=SCALAR_ABS_TOL):
            raise _differs(name, a, b)
        return
    if a != b:
        raise _differs(name, a, b)


def _compare_sequence(name: str, a: Sequence[object], b: Sequence[object]) -> None:
    if len(a) != len(b):
        raise ValueError(
            f"tape parameter {name} differs from the experiment's: "
            f"tape has {len(a)} entries, experiment {len(b)}"
        )
    x: object  # both sequences as arrays when all numbers, else each pair of entries
    y: object
    if _all_numbers(a) and _all_numbers(b):
        x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        scale = max(float(np.max(np.abs(x), initial=0.0)), float(np.max(np.abs(y), initial=0.0)))
        bad = ~np.isclose(x, y, rtol=REL_TOL, atol=SEQUENCE_ABS_TOL * scale)
        if np.any(bad):
            i = int(np.argmax(bad))
            raise _differs(f"{name}[{i}]", a[i], b[i])
        return
    for i, (x, y) in enumerate(zip(a, b, strict=True)):
        _compare(f"{name}[{i}]", x, y)
