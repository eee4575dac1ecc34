"""What the ISU laboratory's procedures are told of the station config: its site and its
noise specification (both `station day` and `station align` hand them to the check-sheets)."""

from __future__ import annotations

import numpy as np

from procedures.isu.calibration import NoiseSpec
from procedures.isu.site import Site
from station.config.calibration import CalibrationOptions
from station.config.isu import StationConfig


def site_of(cfg: StationConfig) -> Site:
    """The laboratory's site (latitude, local g, Earth rate) from the station config."""
    s = cfg.site
    return Site(latitude_deg=s.latitude_deg, g_local_mps2=s.g_local_mps2,
                earth_rate_deg_per_hr=s.earth_rate_deg_per_hr)


def mounting(cfg: StationConfig) -> np.ndarray:
    """T^BI of the unit as the station bolts it (``[isu] t_bi_rotation_deg``): what the
    accuracy prediction takes before a survey (the day's survey recovers it to arcseconds,
    and II-6 then predicts from the survey's)."""
    from sim.frames import transform_of_rotated

    return transform_of_rotated(np.radians(np.array(cfg.isu.t_bi_rotation_deg, dtype=float)))


def noise_spec(cfg: StationConfig) -> NoiseSpec:
    """The laboratory's noise specification (what the error model of II-4 assumes)."""
    g = cfg.isu.gyros[0]
    a = cfg.isu.accels[0]
    env = cfg.environment
    tb = cfg.table
    ins = cfg.instruments
    return NoiseSpec(
        gyro_arw_deg_rt_hr=g.arw_deg_rt_hr,
        gyro_drift_sigma_deg_hr=g.drift_sigma_deg_hr,
        gyro_drift_tau_s=g.drift_tau_s,
        gyro_sample_rate_hz=g.pulse_rate_hz,
        accel_white_micro_g_rt_hz=a.noise_micro_g_rt_hz,
        vibration_rms_micro_g=env.vibration.rms_micro_g,
        vibration_band_hz=tuple(env.vibration.band_hz),
        bubble_noise_arcsec=ins.bubble_level.noise_arcsec,
        bubble_graduation_arcsec=ins.bubble_level.resolution_arcsec,
        table_setting_arcsec=tb.setting_noise_arcsec,
        resolver_cyclic_arcsec=tb.resolver_error_arcsec,
        nonorthogonality_arcsec=tb.nonorthogonality_arcsec,
        autocollimator_arcsec=ins.autocollimator.noise_arcsec,
        tilt_diurnal_pp_arcsec=env.pier_tilt.diurnal_pp_arcsec,
        tilt_diurnal_azimuth_deg=env.pier_tilt.diurnal_azimuth_deg,
        tilt_wander_sigma_arcsec=env.pier_tilt.wander_sigma_arcsec,
        tilt_wander_tau_s=env.pier_tilt.wander_tau_s,
        wobble_amplitude_arcsec=env.wobble.amplitude_arcsec,
        wobble_period_s=env.wobble.period_s,
        wobble_coherence_s=env.wobble.coherence_s,
        gyro_sample_clock_ppm=(cfg.calibration or CalibrationOptions()).gyro_sample_clock_ppm,
        oscillator_frequency_error=abs(cfg.oscillator.frequency_error),
        oscillator_drift_per_day=abs(cfg.oscillator.drift_per_day),
    )
