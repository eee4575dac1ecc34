"""Physical parameters of the simulated ISU laboratory, in the lab's units.

The values themselves (truth and noise) live in ``config/default.toml`` with the reasoning
for each magnitude; these models give them names, units and bounds. Every magnitude is
bounded: a bound is either what the simulation can represent (a time constant against its
knot step, a frequency against double precision) or what an instrument of the class can
be (a generous multiple of the class's figures, never tuned to the default values).
Strict types: a TOML string or boolean is never taken for a number.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationInfo,
    field_validator,
)

# Knot steps of the noise processes (sim.isu.environment.Environment.WANDER_KNOT and
# sim.isu.unit.DRIFT_KNOT; tests/test_config_bounds.py checks they agree). A Gauss-Markov
# process is held at knots and linear between them: with tau >= 10 knots the variance
# between knots is within 5 % of sigma^2 (it is sigma^2 (1 + exp(-h/tau)) / 2 at mid-knot).
WANDER_KNOT_S = 60.0
DRIFT_KNOT_S = 10.0
KNOTS_PER_TAU = 10
MAX_TAU_S = 1e9  # 30 years: longer is a constant over any run
G_MAX = 1.1  # g: the largest specific force an ISU sees on the table (gravity + vibration)
# What report 000's charts ask of the table and the gyros (procedures.isu.plan.DayPlan, the
# table driver's wait; tests/test_config_bounds.py checks them against the code):
TOP_RATE_DEG_S = 15.0  # II-6.2 turns and II-10's top rate
RAMP_DEG_S2 = 5.0  # II-10's rate ramps
MOVE_WAIT_S = 120.0  # a position setting must hold within the driver's wait_still
SETTLE_TAUS = 6.64  # sim.isu.trajectory.plan_move settles in 6.64 time constants
# The rebalance range must hold the top rate, the Earth rate and the largest error terms
# (R, B at 1 g, C at 1 g^2 at their bounds): a gyro that saturates gives clipped counts.
MIN_RANGE_DEG_HR = TOP_RATE_DEG_S * 3600 + 15.1 + 100 + 3 * 100 + 5 * 10


def _as_tuple(v: Any) -> Any:
    """TOML arrays arrive as lists; the models hold tuples (strict mode wants the type)."""
    return tuple(v) if isinstance(v, list) else v


AsTuple = BeforeValidator(_as_tuple)
BandHz = Annotated[float, Field(ge=0.1, le=1000.0)]  # floor vibration; velocity ~ 1/(2 pi f)
TiltArcsec = Annotated[float, Field(ge=-60.0, le=60.0)]  # within half the levels' range
AxisDeg = Annotated[float, Field(ge=-180.0, le=180.0)]
# Misalignments: the calibration's models are first order; at 600 arcsec the neglected
# m^2/2 is 0.9 arcsec, below the autocollimators' 1 arcsec noise.
MisalignArcsec = Annotated[float, Field(ge=-600.0, le=600.0)]
# Bolted within tenths of a degree; the survey's autocollimators search +-3 deg around the
# nominal aim for the mirrors (Chart I-2 step 2), so 2 deg leaves room for the base.
MountDeg = Annotated[float, Field(ge=-2.0, le=2.0)]


class _Model(BaseModel):
    model_config = ConfigDict(defer_build=True,
                              extra="forbid", frozen=True, allow_inf_nan=False, strict=True)


def _tau(knot_s: float) -> Any:
    return Field(ge=KNOTS_PER_TAU * knot_s, le=MAX_TAU_S)


class SiteParams(_Model):
    # The ISU laboratory calibrates at any latitude; a gyrocompass alignment near a pole is
    # the alignment command's to refuse (its accuracy goes as 1/cos(latitude)).
    latitude_deg: float = Field(ge=-90, le=90)
    g_local_mps2: float = Field(gt=9.7, lt=9.9)  # 9.78 (equator) .. 9.83 (poles), altitude
    earth_rate_deg_per_hr: float = Field(ge=15.0, le=15.1)  # 15.041: the Earth's, nothing else


class PierTiltParams(_Model):
    # Tilts: the bubble levels read +-120 arcsec; each term is bounded well inside that.
    diurnal_pp_arcsec: float = Field(ge=0, le=60)
    diurnal_azimuth_deg: float = Field(ge=-360, le=360)
    wander_sigma_arcsec: float = Field(ge=0, le=10)
    wander_tau_s: float = _tau(WANDER_KNOT_S)


class WobbleParams(_Model):
    amplitude_arcsec: float = Field(ge=0, le=10)
    period_s: float = Field(ge=1, le=3600)  # a wobble: about a cycle a minute
    coherence_s: float = Field(ge=1, le=MAX_TAU_S)

    @field_validator("coherence_s")
    @classmethod
    def _coherent_over_a_period(cls, v: float, info: ValidationInfo) -> float:
        """The tones span 1/period +- 1/(2 coherence): coherence >= period keeps every
        tone at a positive frequency, and a wobble is an oscillation only if it is."""
        period = info.data.get("period_s")
        if period is not None and not v >= period:
            raise ValueError(f"must be at least period_s ({period} s)")
        return v


class VibrationParams(_Model):
    rms_micro_g: float = Field(ge=0, le=10_000)  # 10 milli-g rms is no laboratory floor
    band_hz: Annotated[tuple[BandHz, BandHz], AsTuple]
    tones: int = Field(ge=1, le=200)

    @field_validator("band_hz")
    @classmethod
    def _band_in_order(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not v[0] < v[1]:
            raise ValueError("the low edge must be below the high edge")
        return v


class EnvironmentParams(_Model):
    pier_tilt: PierTiltParams
    wobble: WobbleParams
    vibration: VibrationParams


class TableParams(_Model):
    # Imperfections of a precision table (arcsec); bounded where the charts' checks refuse
    # the table: at 60 arcsec of resolver error the survey's trunnion check (Chart I-2
    # step 5a) fails, and every setting must land within the 10 arcsec the procedures
    # allow (Chart I-1 step 7, I-2 step 2): 3 sigma of the setting noise.
    resolver_error_arcsec: float = Field(ge=0, le=20)
    setting_noise_arcsec: float = Field(ge=0, le=3)
    nonorthogonality_arcsec: float = Field(ge=0, le=60)
    base_tilt_arcsec: Annotated[tuple[TiltArcsec, TiltArcsec], AsTuple]
    base_azimuth_arcsec: float = Field(ge=-600, le=600)  # the autocollimators see +-0.5 deg
    slew_rate_deg_s: float = Field(gt=0, le=100)
    slew_accel_deg_s2: float = Field(gt=0, le=1000)
    settle_tau_s: float = Field(gt=0, le=60)
    overshoot_arcsec: float = Field(ge=0, le=600)
    max_rate_deg_s: float = Field(ge=TOP_RATE_DEG_S, le=100)
    max_accel_deg_s2: float = Field(ge=RAMP_DEG_S2, le=1000)
    trunnion_range_deg: Annotated[tuple[AxisDeg, AxisDeg], AsTuple]
    resolver_resolution_arcsec: float = Field(ge=1e-4, le=60)

    @field_validator("settle_tau_s")
    @classmethod
    def _a_half_turn_settles_in_time(cls, v: float, info: ValidationInfo) -> float:
        """The longest move, half a turn, slews and settles within the driver's wait
        (with 20 s to spare): 180/rate + rate/accel + 6.64 tau <= 100 s."""
        rate, acc = info.data.get("slew_rate_deg_s"), info.data.get("slew_accel_deg_s2")
        if rate is None or acc is None:
            return v
        t = 180.0 / rate + rate / acc + SETTLE_TAUS * v
        if t > MOVE_WAIT_S - 20.0:
            raise ValueError(
                f"with slew_rate_deg_s = {rate} and slew_accel_deg_s2 = {acc}, a 180 deg move "
                f"would take {t:.0f} s to settle: at most {MOVE_WAIT_S - 20:.0f} s (the "
                f"procedures wait {MOVE_WAIT_S:.0f} s for the table to hold)")
        return v

    @field_validator("trunnion_range_deg")
    @classmethod
    def _range_in_order(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not v[0] < v[1]:
            raise ValueError("the low end must be below the high end")
        return v


Misalignment = Annotated[tuple[MisalignArcsec, MisalignArcsec], AsTuple]


class GyroParams(_Model):
    # Error terms: at most about 100 times the GG334A class's (bias 1 deg/hr, unbalance
    # 1 deg/hr/g, compliance 0.1 deg/hr/g^2; DOMAIN.md), so every one stays a small part
    # of the rebalance range at 1 g and the table's 15 deg/s stays inside that range.
    scale_factor_arcsec_per_pulse: float = Field(ge=0.01, le=100)
    misalignment_arcsec: Misalignment
    spin_axis_rotation_arcsec: float = Field(ge=-600, le=600)
    R_deg_hr: float = Field(ge=-100, le=100)
    B_I_deg_hr_g: float = Field(ge=-100, le=100)
    B_O_deg_hr_g: float = Field(ge=-100, le=100)
    B_S_deg_hr_g: float = Field(ge=-100, le=100)
    C_II_deg_hr_g2: float = Field(ge=-10, le=10)
    C_SS_deg_hr_g2: float = Field(ge=-10, le=10)
    C_IS_deg_hr_g2: float = Field(ge=-10, le=10)
    C_OS_deg_hr_g2: float = Field(ge=-10, le=10)
    C_IO_deg_hr_g2: float = Field(ge=-10, le=10)
    Q_II_hr_deg: float = Field(ge=-1e-7, le=1e-7)  # 0.5 % of the rate at 15 deg/s
    Q_IS_hr_deg: float = Field(ge=-1e-7, le=1e-7)
    J_hr: float = Field(ge=-1e-5, le=1e-5)  # output-axis inertia / H: 36 ms at most
    arw_deg_rt_hr: float = Field(ge=0, le=1)  # 300 times the class's 0.003
    drift_sigma_deg_hr: float = Field(ge=0, le=1)  # 200 times the class's 0.005
    drift_tau_s: float = _tau(DRIFT_KNOT_S)
    pulse_rate_hz: float = Field(ge=100, le=1e6)

    @field_validator("pulse_rate_hz")
    @classmethod
    def _range_covers_the_earth(cls, v: float, info: ValidationInfo) -> float:
        """The rebalance range (pulse rate x scale factor; arcsec/s = deg/hr) must hold the
        table's top rate, the Earth rate and the largest error terms at 1 g."""
        sf = info.data.get("scale_factor_arcsec_per_pulse")
        if sf is not None and v * sf < MIN_RANGE_DEG_HR:
            raise ValueError(
                f"with scale_factor_arcsec_per_pulse = {sf} the rebalance range is "
                f"{v * sf:.4g} deg/hr: it must be at least {MIN_RANGE_DEG_HR:.0f} deg/hr "
                f"(the table's {TOP_RATE_DEG_S:g} deg/s, the Earth rate and the largest error "
                "terms at 1 g)")
        return v


class AccelParams(_Model):
    D1_pps_per_g: float = Field(ge=10, le=1e5)
    D0_g: float = Field(ge=-0.01, le=0.01)  # 100 times the class's 1e-4 g
    D2_g_per_g2: float = Field(ge=-0.01, le=0.01)
    D3_g_per_g3: float = Field(ge=-0.01, le=0.01)
    misalignment_arcsec: Misalignment
    f0_hz: float = Field(ge=1000, le=100_000)  # vibrating strings: tens of kHz
    common_mode_hz_per_g2: float = Field(ge=-1000, le=1000)
    noise_micro_g_rt_hz: float = Field(ge=0, le=1000)  # 100 times the class's 10

    @field_validator("common_mode_hz_per_g2")
    @classmethod
    def _strings_keep_ringing(cls, v: float, info: ValidationInfo) -> float:
        """Each string runs at f0 -+ D1 u / 2 + kappa u^2: at G_MAX g it must keep at
        least half its frequency, or the string stops (and the counts go negative)."""
        d1, f0 = info.data.get("D1_pps_per_g"), info.data.get("f0_hz")
        if d1 is None or f0 is None:
            return v
        low = f0 - 0.5 * d1 * G_MAX - abs(v) * G_MAX**2
        if low < 0.5 * f0:
            raise ValueError(
                f"with D1_pps_per_g = {d1} and f0_hz = {f0}, the slower string would run at "
                f"{low:.4g} Hz at {G_MAX} g, under half of f0")
        return v

    def fastest_string_hz(self) -> float:
        """The higher string frequency at G_MAX g (for the IEU's 16-bit registers)."""
        return (self.f0_hz + 0.5 * self.D1_pps_per_g * G_MAX
                + abs(self.common_mode_hz_per_g2) * G_MAX**2)


class IsuParams(_Model):
    t_bi_rotation_deg: Annotated[tuple[MountDeg, MountDeg, MountDeg], AsTuple]
    mirror_nonorthogonality_arcsec: float = Field(ge=-600, le=600)
    gyros: Annotated[tuple[GyroParams, GyroParams, GyroParams], AsTuple]
    accels: Annotated[tuple[AccelParams, AccelParams, AccelParams], AsTuple]


class OscillatorParams(_Model):
    # A quartz master oscillator runs at 1-10 MHz; above 100 MHz the phase of a long run
    # (1e6 s: 1e14 cycles) keeps no sub-cycle resolution in double precision.
    nominal_hz: float = Field(ge=1e5, le=1e8)
    s1_divider: int = Field(ge=1, le=1_000_000)
    s2_divider: int = Field(ge=1, le=1_000_000)
    frequency_error: float = Field(ge=-1e-4, le=1e-4)  # 100 ppm: the loosest crystal
    drift_per_day: float = Field(ge=-1e-6, le=1e-6)  # 1 ppm/day: an unaged crystal, at worst


class WorldParams(_Model):
    site: SiteParams
    environment: EnvironmentParams
    table: TableParams
    isu: IsuParams
    oscillator: OscillatorParams
