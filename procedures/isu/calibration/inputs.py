"""What the calibration computations take in (Chart II-15 steps 3-7), in the lab's units.

* ``Constants``: step 3 (g, Earth rate components, counter and rotation-pulse scale factors)
  and step 4 (second columns of T^BRm for m = 1, 3, 5, 13, 14, 15, Survey Results Sheet),
  and phi1 at the survey's levelled position 0 (beyond the print: R1's tilt at phi1 = 90).
* ``GyroPosition`` / ``AccelPosition``: steps 5-6 (counter settings and outputs, Counter
  Settings and Counter Outputs Sheets), one record per position; partial lists are allowed
  (step 5 comment): the computations then give exactly the constants of Chart II-16.
* ``last_d1d3``: step 7, the last (D1 D3) of each accelerometer when positions 13 and 14
  were not performed.
* ``prior_gyro``: step 3 of a partial calibration (Chart II-16's prerequisites in
  parentheses): [(G_k.B_j)/DeltaPhi] of an earlier Calibration Results Sheet for the pairs
  (2j-1, 2j) this run did not measure, with its standard error.
* ``TableGeometry`` (optional): T^BI, the position-0 resolver readings and the resolver
  settings of the survey; used only to predict how table errors map into each position.

Units: g in g; Earth rate in deg/hr; S1^T in seconds per counter clock tick; S^phi in
degrees per rotation pulse; counts in pulses or ticks; times in seconds of laboratory time.
"""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

Vec3 = tuple[float, float, float]
StringKey = tuple[int, int]  # (accelerometer k, string l), as the subscript kl of Chart II-20

GYRO_POSITIONS = tuple(range(1, 16))
TURNING_POSITIONS = (1, 2, 3, 4, 5, 6)
ACCEL_POSITIONS = tuple(range(7, 16))
SURVEY_POSITIONS = (1, 3, 5, 13, 14, 15)
EXTRA_FIRST = 16  # the first extra accelerometer position (beyond the manual's 1-15)


class _In(BaseModel):
    model_config = ConfigDict(defer_build=True, extra="forbid", frozen=True, allow_inf_nan=False)


class Constants(_In):
    """Chart II-15 steps 3 and 4 (from the Survey Results Sheet, Chart I-3)."""

    g: float = Field(gt=0.9, lt=1.1, description="local gravity, in g")
    w_sin_lambda: float = Field(description="Earth rate, north component, deg/hr (colatitude)")
    w_cos_lambda: float = Field(description="Earth rate, vertical component, deg/hr")
    s1_t: float = Field(gt=0, description="S1^T, seconds per counter clock tick")
    s_phi: float = Field(gt=0, description="S^phi, degrees of table turn per rotation pulse")
    t_br_column2: dict[int, Vec3] = Field(
        description="m -> (T12, T22, T32)^BRm, body components of the rotary frame's R2"
    )
    phi1_level_deg: float = Field(
        0.0, ge=-1.0, le=1.0, description="phi1 read with the rotary axis up (survey "
        "position 0, levelled); 0 when not surveyed so"
    )

    @property
    def w_along_r1(self) -> float:
        """Earth rate along +R1 at phi1 = 90 deg, deg/hr (positions 1-6, II-7). R1 points
        south and, the trunnion being read from a zero phi1_level off the vertical, dips
        below the horizontal by phi1_level: -W sin(lambda) cos(e) + W cos(lambda) sin(e),
        e = -phi1_level. The print's -W sin(lambda) takes e = 0; the default laboratory's
        14 arcsec put DeltaPhi 1.3e-8 high (0.2 sigma with quiet gyros)."""
        e = self.r1_elevation
        return self.w_cos_lambda * math.sin(e) - self.w_sin_lambda * math.cos(e)

    @property
    def r1_elevation(self) -> float:
        """R1's elevation above the horizontal at phi1 = 90 deg, rad (``w_along_r1``)."""
        return -math.radians(self.phi1_level_deg)

    @field_validator("t_br_column2")
    @classmethod
    def _survey_positions(cls, v: dict[int, Vec3]) -> dict[int, Vec3]:
        bad = sorted(set(v) - set(SURVEY_POSITIONS))
        if bad:
            raise ValueError(f"T^BRm columns are given for m = 1, 3, 5, 13, 14, 15 only: {bad}")
        return v


class GyroPosition(_In):
    """One gyro position's counter settings and outputs.

    Positions 1-6 (Chart II-6, "measure Z" on the rotation pulses): ``n_phi`` rotation pulses
    (the preset), ``n1`` clock ticks on counter 1 over them, ``delta`` net gyro counts on
    counters 2-4. Positions 7-15 (Charts II-11, II-12, "measure Z" on the clock): ``n1`` clock
    ticks (the preset) and ``delta`` the gyro counts over them. With II-5.2's pulse gate
    ("measure X-Y" on each gyro's net train), gyro k's own gate is ``n1_each[k - 1]`` clock
    ticks for the ``delta[k - 1]`` pulses preset (``pulse_gated``); a gyro counted over the
    clock gate instead has ``n1_each`` = ``n1``.
    """

    n1: float = Field(gt=0, description="clock ticks in the gate")
    n_phi: float | None = Field(default=None, description="rotation pulses (positions 1-6)")
    delta: Vec3 = Field(description="net counts of gyros 1, 2, 3")
    t0: float = Field(description="gate start, s")
    t1: float = Field(description="gate end, s")
    n1_each: Vec3 | None = Field(default=None, description="clock ticks of each gyro's gate")
    pulse_gated: tuple[bool, bool, bool] = (False, False, False)

    @model_validator(mode="after")
    def _own_gates(self) -> GyroPosition:
        if any(self.pulse_gated) and self.n1_each is None:
            raise ValueError("a pulse-gated gyro position needs n1_each (clock ticks per gyro)")
        if self.n1_each is not None and min(self.n1_each) <= 0:
            raise ValueError("n1_each: every gyro's gate must hold clock ticks")
        return self


class AccelPosition(_In):
    """One accelerometer position (Charts II-13, II-14, "measure X-Y" on each string).

    Counter (k, l) counts ``n1[(k, l)]`` clock ticks while string l of accelerometer k gives
    its preset ``gamma[(k, l)]`` pulses; all gates open together at ``t0``. ``t_level`` is the
    time of the bubble-level reading used for the level correction of phi1 and phi3.
    """

    gamma: dict[StringKey, float]
    n1: dict[StringKey, float]
    t0: float
    t1: float
    t_level: float

    @field_validator("gamma", "n1", mode="before")
    @classmethod
    def _string_keys(cls, v: object) -> object:
        """Accept (k, l) tuples and, for JSON round trips, "k,l" or "kl" strings."""
        if not isinstance(v, dict):
            return v
        out = {}
        for key, val in v.items():
            if isinstance(key, str):
                digits = [c for c in key if c.isdigit()]
                key = (int(digits[0]), int(digits[-1]))
            out[tuple(key)] = val
        return out

    @model_validator(mode="after")
    def _same_counters(self) -> AccelPosition:
        if set(self.gamma) != set(self.n1):
            raise ValueError("gamma and n1 must name the same (k, l) counters")
        for k, s in self.gamma:
            if k not in (1, 2, 3) or s not in (1, 2):
                raise ValueError(f"no string ({k}, {s}): k in 1..3, l in 1..2")
        return self


class ExtraAccelPosition(AccelPosition):
    """An accelerometer position beyond the manual (issue 19, ``extra_accel``): the table set
    as positions 7-15 (phi1 = 0, phi2 = 90, level corrections) at resolver setting
    ``setting_deg`` (phi3, phi4), which puts the body's ``up`` vertical with ``north`` north
    (nominal body components, from the survey's T^BI and the gimbal chain of Chart I-4)."""

    up: Vec3
    north: Vec3
    setting_deg: tuple[float, float]


class TableGeometry(_In):
    """Survey results that fix how table errors turn the body at each position (optional).

    ``t_bi`` is T^BI (rows: body axes in inner-frame components), ``phi0_deg`` the resolver
    readings (phi1..phi4) at position 0, ``settings_deg`` the resolver settings (phi3, phi4)
    of positions 1, 3, 5, 13, 14, 15 (Chart I-5); even positions are phi3 + 180 deg.
    ``uncorrected``: the static kinds ("G" gyro, "A" accelerometer) set without bubble-level
    corrections (II-6.1), keeping the survey's level reading.
    """

    t_bi: tuple[Vec3, Vec3, Vec3]
    phi0_deg: tuple[float, float, float, float]
    settings_deg: dict[int, tuple[float, float]]
    uncorrected: tuple[str, ...] = ()
    precision_arcsec: dict[str, float] = {}  # kind -> resolver-setting precision (II-6.1)

    @property
    def levelled(self) -> bool:
        """Position 0 had the rotary axis up (phi1 within a degree of 0): the survey read the
        levels there, so phi1^0 is the trunnion's reading of the level table."""
        return abs(self.phi0_deg[0]) < 1.0

    @property
    def phi1_level_deg(self) -> float:
        """``Constants.phi1_level_deg`` from this survey: phi1^0 when levelled, else 0."""
        return self.phi0_deg[0] if self.levelled else 0.0


class CalibrationData(_In):
    """Everything Chart II-15 enters before step 8, for a full or partial calibration."""

    constants: Constants
    gyro: dict[int, GyroPosition] = Field(default_factory=dict)
    accel: dict[int, AccelPosition] = Field(default_factory=dict)
    last_d1d3: dict[int, float] = Field(
        default_factory=dict, description="accelerometer k -> last (D1 D3), (pulses/s)/g^3"
    )
    last_d1d3_sigma: dict[int, float] = Field(
        default_factory=dict, description="standard error of the supplied (D1 D3), if known"
    )
    prior_gyro: dict[int, dict[int, tuple[float, float]]] = Field(
        default_factory=dict,
        description="gyro k -> j -> ([(G_k.B_j)/DeltaPhi] pulses/deg, its sigma) carried "
        "from an earlier Calibration Results Sheet")
    geometry: TableGeometry | None = None
    # positions beyond the manual (m >= EXTRA_FIRST): fitted by the all-positions estimator
    # only, the closed forms ignore them
    extra_accel: dict[int, ExtraAccelPosition] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _positions(self) -> CalibrationData:
        for m, p in self.gyro.items():
            if m not in GYRO_POSITIONS:
                raise ValueError(f"gyro position {m} is not one of 1..15")
            if m in TURNING_POSITIONS and p.n_phi is None:
                raise ValueError(f"gyro position {m} needs n_phi (rotation pulses)")
        for m in self.accel:
            if m not in ACCEL_POSITIONS:
                raise ValueError(f"accelerometer position {m} is not one of 7..15")
        for m in self.extra_accel:
            if m < EXTRA_FIRST:
                raise ValueError(f"extra accelerometer position {m}: numbered from {EXTRA_FIRST}")
        for k in (*self.last_d1d3, *self.last_d1d3_sigma):
            if k not in (1, 2, 3):
                raise ValueError(f"no accelerometer {k}")
        for k, js in self.prior_gyro.items():
            if k not in (1, 2, 3) or not set(js) <= {1, 2, 3}:
                raise ValueError(f"prior_gyro: no gyro {k} or axis in {sorted(js)}")
        return self
