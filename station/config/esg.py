"""Configuration of the ESG laboratory: a TOML file with an ``[esg]`` section.

Scalars of the gyro and the site at the top of the section; ``[esg.pattern]`` and
``[esg.signal]`` hold the pattern and the pickoff-signal magnitudes. A bad or unknown
field is refused with a message naming it (esg.pattern.roughness_rms_in, ...).

Bounds: the pattern's and the signal's keep the simulated processor's pulses countable;
the rotor's come from the calibration's own timing (a test checks these figures against
procedures.esg.acquisition.EsgPlan): it waits for 248 rps, so the rotor must spin up to
at least 250 (the report's operating speed, usable to 500); over three hours (the longest
calibration seen took 2.8 h) a rundown must leave it above the usable 200 rps, so
tau >= 3 h / ln(250/200) = 13.4 h; the
console damps for 900 s, so the damping time constant is at most a third of that, and at
least two of the rotor's 5-s integration steps (RK4: accurate to 1e-4 per step there).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Literal, TypeVar

from pydantic import (
    BaseModel,
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)

from sim.esg.pattern import PatternSpec
from sim.esg.world import EsgParams
from station.config.file import read_section
from station.config.limits import EsgLimits
from station.config.strict import STRICT

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

_D = TypeVar("_D", bound="DataclassInstance")

# Where the three pickoffs make equal angles with the spin axis, for mirrors 89 deg 56 min
# 5 sec apart (procedures.esg.mechanization.equal_ratio_colatitude; a test ties the two)
EQUAL_RATIO_COLATITUDE_DEG = 54.72
# The lines' end at least a degree short of it (the spin axis's pointing and drift); on a
# cosine pattern 3.7 deg: nearer, step 6's pickoff at 180 deg - 54.72 sits close enough to
# the lower extremity for its logic gate to meet line 2 (docs/esg-options.md: 52.5 deg
# stopped one seed in three there, 51 none of six)
TOP_LIMIT_DEG = {"great_circle": 53.7, "cosine": 51.0}
EXTREMITY_MARGIN_DEG = 1.0  # ESG-DPX's pickoff 2 this far past the lines' end, at most


class PatternConfig(BaseModel):
    """The pattern's drawing and flaws. The drawing must be one the calibration can use:
    its lines end short of the equal-ratio colatitude, and a great circle is inclined
    enough to reach that end (the validators below; docs/esg.md, "Admitted patterns")."""

    model_config = STRICT
    kind: Literal["great_circle", "cosine"] | None = None
    inclination_deg: float | None = Field(None, gt=10.0, lt=80.0)
    top_colatitude_deg: float | None = Field(None, ge=30.0, le=60.0)
    application_in: float | None = Field(None, ge=0, le=0.002)
    roughness_rms_in: float | None = Field(None, ge=0, le=0.001)
    # the roughness is tabulated every corr/6 of arc: 1e-3 in is 2e4 points per edge
    roughness_corr_in: float | None = Field(None, ge=0.001, le=0.1)
    d0_sd_in: float | None = Field(None, ge=0, le=0.01)

    @field_validator("top_colatitude_deg")
    @classmethod
    def _ends_short_of_the_equal_ratio_point(cls, v: float | None,
                                             info: ValidationInfo) -> float | None:
        """Steps 4 and 6 set pickoffs at the equal-ratio colatitude and its mirror image
        below the equator: the lines must reach past both (TOP_LIMIT_DEG)."""
        kind = info.data.get("kind") or PatternSpec().kind
        if v is not None and v > TOP_LIMIT_DEG[kind]:
            raise ValueError(
                f"lines that end at colatitude {v:g} deg leave too little pattern around "
                f"the equal-ratio colatitude {EQUAL_RATIO_COLATITUDE_DEG:g} deg (steps 4 "
                f"and 6): at most {TOP_LIMIT_DEG[kind]:g} on a {kind.replace('_', ' ')}")
        return v

    @model_validator(mode="after")
    def _great_circle_reaches_the_end(self) -> PatternConfig:
        """A great circle's edge F = d exists at colatitude th only where
        sin(i) sin(th) - cos(i) cos(th) = -cos(i + th) >= |d|: every edge, the logic line's
        leading edge farthest out (3 sd of the set-up offsets), must exist a degree past
        the lines' end, where sheet ESG-DPX sets pickoff 2 on them."""
        spec = PatternSpec()
        if (self.kind or spec.kind) != "great_circle":
            return self
        incl = self.inclination_deg or spec.inclination_deg
        top = self.top_colatitude_deg or spec.top_colatitude_deg
        d0_sd = spec.d0_sd_in if self.d0_sd_in is None else self.d0_sd_in
        d_max = (spec.width_in / 2 + spec.logic_gap_in + spec.logic_width_in
                 + 3.0 * (d0_sd + spec.logic_offset_sd_in))
        least = 90.0 + math.degrees(math.asin(d_max)) - top - EXTREMITY_MARGIN_DEG
        if incl < least:
            raise ValueError(
                f"inclination_deg = {incl:g} with top_colatitude_deg = {top:g}: the great "
                f"circle does not reach the lines' end (its logic line's edge, {d_max:.3f} "
                f"in from the circle, needs an inclination of at least {least:.2f} deg)")
        return self


class SignalConfig(BaseModel):
    model_config = STRICT
    jitter_ns: float | None = Field(None, ge=0, le=10000)
    arc_rate_per_rev: float | None = Field(None, ge=0, le=10)
    arc_wide_fraction: float | None = Field(None, ge=0, le=1)


class ReductionConfig(BaseModel):
    """The data reduction's choices (report 004, "Data Reduction Technique")."""

    model_config = STRICT
    # eq. 11's polynomial order: 5..9 (the report's trials; it used 7) or "residuals", each
    # schedule's choice by the order trials' prediction residuals
    order: Literal[5, 6, 7, 8, 9, "residuals"] = 7


class ProcedureConfig(BaseModel):
    """The acquisition's choices (report 004, "Before data taking")."""

    model_config = STRICT
    # sheet ESG-DPX: lamps, discriminator and delay set up at the pattern extremity after
    # spin-up (false: the processor's preset 20 us and 241 us, lamps as delivered)
    extremity_setup: bool = True
    # the data processor's time-interval counters: 2 as the report's (two pickoffs at a
    # time), 3 for the simultaneous three-pickoff acquisition (docs/esg-options.md)
    counters: Literal[2, 3] = 2
    # the strategy study's variants and Figure 3 written into the record (report 004,
    # "Pattern Analysis"; docs/esg-options.md), averaged over this many orientations
    strategy_variants: bool = False
    strategy_variants_points: int = Field(5000, ge=500, le=100000)
    # step 1 and ESG-PA: shim the mount / translate pickoff 1 when the coning check finds
    # them beyond 3 / 15 arcsec, up to alignment_iterations times, instead of stopping
    adjust_alignment: bool = False
    alignment_iterations: int = Field(3, ge=1, le=10)
    # sheet ESG-PA2 before step 1: the case remounted with mirror 2 along the spindle and
    # pickoff 2 adjusted the same way, then mounted back; after step 3 pickoff 3's tilt
    # towards mirror 1 measured and translated out (report 004, "Mirror and Pickoff
    # Alignment"; implies adjust_alignment)
    remount_alignment: bool = False
    # with the remount: pickoff 3's tilt towards mirror 2 measured and translated out too,
    # in a second remount after step 3 (about 3 h more; implies remount_alignment)
    pickoff3_mirror2: bool = False


class EsgConfig(BaseModel):
    model_config = STRICT
    latitude_deg: float | None = Field(None, ge=-89.0, le=89.0)
    spin_rps: float | None = Field(None, ge=250.0, le=500.0)
    rundown_tau_h: float | None = Field(None, ge=13.5, le=1e6)
    unbalance_dyne_cm: float | None = Field(None, ge=0, le=100)
    electric_deg_h: float | None = Field(None, ge=0, le=10)
    damping_tau_s: float | None = Field(None, ge=10.0, le=300.0)
    pattern: PatternConfig = PatternConfig.model_validate({})
    signal: SignalConfig = SignalConfig.model_validate({})
    reduction: ReductionConfig = ReductionConfig.model_validate({})
    procedure: ProcedureConfig = ProcedureConfig.model_validate({})
    limits: EsgLimits = EsgLimits()  # acceptance limits (station/config/limits.py)


def _set(obj: _D, model: BaseModel) -> _D:
    """``obj`` with the fields ``model`` sets (not None, not a sub-table) replaced."""
    return replace(obj, **{k: v for k, v in model.model_dump().items()
                           if v is not None and not isinstance(v, dict)})


def params_from(cfg: EsgConfig) -> EsgParams:
    """The default EsgParams with ``cfg`` applied: the section's scalars are the rotor's
    (site latitude included), its tables the pattern's and the signal's."""
    p = EsgParams()
    return replace(p, rotor=_set(p.rotor, cfg), pattern=_set(p.pattern, cfg.pattern),
                   signal=_set(p.signal, cfg.signal), counters=cfg.procedure.counters)


def load_esg_params(path: str | Path | None) -> EsgParams:
    """The default EsgParams with the file's [esg] settings applied."""
    if path is None:
        return EsgParams()
    cfg = read_section(path, "esg", EsgConfig, "ESG")
    return params_from(cfg)


def load_esg_reduction(path: str | Path | None) -> ReductionConfig:
    """The ``[esg.reduction]`` of an ESG file (defaults without one)."""
    if path is None:
        return ReductionConfig.model_validate({})
    return read_section(path, "esg", EsgConfig, "ESG").reduction


def load_esg_procedure(path: str | Path | None) -> ProcedureConfig:
    """The ``[esg.procedure]`` of an ESG file (defaults without one)."""
    if path is None:
        return ProcedureConfig.model_validate({})
    return read_section(path, "esg", EsgConfig, "ESG").procedure


def load_esg_limits(path: str | Path | None) -> EsgLimits:
    """The ``[esg.limits]`` of an ESG file (defaults without one)."""
    if path is None:
        return EsgLimits()
    return read_section(path, "esg", EsgConfig, "ESG").limits
