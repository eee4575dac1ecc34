"""Physical parameters of the simulated ISU laboratory, in the lab's units.

The values themselves (truth and noise) live in ``config/default.toml`` with the reasoning
for each magnitude; these models only give them names, units and validation.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class SiteParams(_Model):
    latitude_deg: float = Field(ge=-90, le=90)
    g_local_mps2: float = Field(gt=9.7, lt=9.9)
    earth_rate_deg_per_hr: float = Field(gt=0)


class PierTiltParams(_Model):
    diurnal_pp_arcsec: float = Field(ge=0)
    diurnal_azimuth_deg: float
    wander_sigma_arcsec: float = Field(ge=0)
    wander_tau_s: float = Field(gt=0)


class WobbleParams(_Model):
    amplitude_arcsec: float = Field(ge=0)
    period_s: float = Field(gt=0)
    coherence_s: float = Field(gt=0)


class VibrationParams(_Model):
    rms_micro_g: float = Field(ge=0)
    band_hz: tuple[float, float]
    tones: int = Field(ge=1, le=200)


class EnvironmentParams(_Model):
    pier_tilt: PierTiltParams
    wobble: WobbleParams
    vibration: VibrationParams


class TableParams(_Model):
    resolver_error_arcsec: float = Field(ge=0)
    setting_noise_arcsec: float = Field(ge=0)
    nonorthogonality_arcsec: float = Field(ge=0)
    base_tilt_arcsec: tuple[float, float]
    base_azimuth_arcsec: float
    slew_rate_deg_s: float = Field(gt=0)
    slew_accel_deg_s2: float = Field(gt=0)
    settle_tau_s: float = Field(gt=0)
    overshoot_arcsec: float = Field(ge=0)
    max_rate_deg_s: float = Field(gt=0)
    max_accel_deg_s2: float = Field(gt=0)
    trunnion_range_deg: tuple[float, float]
    resolver_resolution_arcsec: float = Field(gt=0)


class GyroParams(_Model):
    scale_factor_arcsec_per_pulse: float = Field(gt=0)
    misalignment_arcsec: tuple[float, float]
    spin_axis_rotation_arcsec: float
    R_deg_hr: float
    B_I_deg_hr_g: float
    B_O_deg_hr_g: float
    B_S_deg_hr_g: float
    C_II_deg_hr_g2: float
    C_SS_deg_hr_g2: float
    C_IS_deg_hr_g2: float
    C_OS_deg_hr_g2: float
    C_IO_deg_hr_g2: float
    Q_II_hr_deg: float
    Q_IS_hr_deg: float
    J_hr: float
    arw_deg_rt_hr: float = Field(ge=0)
    drift_sigma_deg_hr: float = Field(ge=0)
    drift_tau_s: float = Field(gt=0)
    pulse_rate_hz: float = Field(gt=0)


class AccelParams(_Model):
    D1_pps_per_g: float = Field(gt=0)
    D0_g: float
    D2_g_per_g2: float
    D3_g_per_g3: float
    misalignment_arcsec: tuple[float, float]
    f0_hz: float = Field(gt=0)
    common_mode_hz_per_g2: float
    noise_micro_g_rt_hz: float = Field(ge=0)


class IsuParams(_Model):
    t_bi_rotation_deg: tuple[float, float, float]
    mirror_nonorthogonality_arcsec: float
    gyros: tuple[GyroParams, GyroParams, GyroParams]
    accels: tuple[AccelParams, AccelParams, AccelParams]


class OscillatorParams(_Model):
    nominal_hz: float = Field(gt=0)
    s1_divider: int = Field(ge=1)
    s2_divider: int = Field(ge=1)
    frequency_error: float
    drift_per_day: float


class WorldParams(_Model):
    site: SiteParams
    environment: EnvironmentParams
    table: TableParams
    isu: IsuParams
    oscillator: OscillatorParams
