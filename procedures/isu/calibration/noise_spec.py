"""The laboratory's instrument and environment specifications, as the error model sees them.

Defaults are the magnitudes of ``config/default.toml`` (the lab's specification sheet);
``tests/test_calibration_math.py`` checks they have not drifted apart.

Pier tilt (Chart I-9's rotational noise) per horizontal axis, tau in seconds, rad^2:

* diurnal: (A^2/2) cos(w_d tau) times cos^2(az) for the east axis, sin^2(az) for north and
  cos(az) sin(az) between them (one rotation axis at azimuth az from east towards north),
  A = peak-to-peak / 2, w_d = 2 pi / 86400;
* wander: s_w^2 exp(-|tau| / tau_w), independent per axis;
* wobble: (a^2/2) cos(2 pi tau / P) sinc(tau / coherence), sinc(x) = sin(pi x)/(pi x): tones
  spread uniformly over 1/coherence Hz about 1/P, independent per axis.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from pydantic import BaseModel, ConfigDict, Field

ARCSEC = math.pi / (180.0 * 3600.0)
DAY = 86400.0


class NoiseSpec(BaseModel):
    model_config = ConfigDict(defer_build=True, extra="forbid", frozen=True, allow_inf_nan=False)

    # --- gyros (Chart IV-2 noise) ---
    gyro_arw_deg_rt_hr: float = Field(0.003, ge=0, description="angle random walk")
    gyro_drift_sigma_deg_hr: float = Field(0.005, ge=0, description="random drift, 1 sigma")
    gyro_drift_tau_s: float = Field(3600.0, gt=0, description="random drift correlation time")
    gyro_sample_rate_hz: float = Field(
        19200.0, gt=0, description="rebalance sampling: pulses exist only at sampling instants"
    )
    count_quantization_var: float = Field(
        1.0 / 6.0, ge=0, description="pulse^2: a count is a difference of two floors"
    )
    gyro_sample_clock_ppm: float | None = Field(
        None, ge=0, description="the rebalance sampling clock against the counter clock, "
        "ppm; None: not known, a clock gate's two edges sample independently "
        "(procedures.isu.calibration.quantization)"
    )
    # --- accelerometers and counters ---
    accel_white_micro_g_rt_hz: float = Field(10.0, ge=0, description="white noise on f2 - f1")
    clock_quantization_var: float = Field(1.0 / 6.0, ge=0, description="tick^2 per clock count")
    string_common_drift_hz: float = Field(
        0.0, ge=0, description="drift of an accelerometer's common string frequency over "
        "the day, 1 sigma (the default lab's strings keep f0)"
    )
    oscillator_frequency_error: float = Field(
        2e-9, ge=0, description="the master oscillator's offset from the nominal frequency "
        "the laboratory records, fractional, 1 sigma (its calibration): every rate a counter "
        "measures is off by it together"
    )
    oscillator_drift_per_day: float = Field(
        1e-10, ge=0, description="the master oscillator's aging, fractional frequency per "
        "day (its specification): every frequency a counter measures drifts with it"
    )
    vibration_rms_micro_g: float = Field(100.0, ge=0, description="floor vibration per axis")
    vibration_band_hz: tuple[float, float] = (2.0, 30.0)
    # --- levels, table, survey ---
    bubble_noise_arcsec: float = Field(0.2, ge=0)
    bubble_graduation_arcsec: float = Field(0.1, ge=0)
    table_setting_arcsec: float = Field(0.3, ge=0, description="servo scatter per setting")
    resolver_cyclic_arcsec: float = Field(1.0, ge=0, description="cyclic error amplitude A")
    resolver_harmonics: tuple[float, float] = Field(
        (0.8, 0.6), description="first and second harmonic amplitudes, in units of A"
    )
    nonorthogonality_arcsec: float = Field(
        1.0, ge=0, description="per component of each gimbal junction's fixed rotation"
    )
    autocollimator_arcsec: float = Field(1.0, ge=0, description="per reading, each angle")
    survey_readings: int = Field(
        60, ge=1, description="autocollimator and level readings averaged by the survey"
    )
    survey_azimuth_arcsec: float = Field(
        0.5, ge=0, description="error of the survey's base-azimuth step (Chart I-2 step 5a)"
    )
    # --- pier tilt ---
    tilt_diurnal_pp_arcsec: float = Field(10.0, ge=0)
    tilt_diurnal_azimuth_deg: float = 35.0
    tilt_wander_sigma_arcsec: float = Field(1.0, ge=0)
    tilt_wander_tau_s: float = Field(10800.0, gt=0)
    wobble_amplitude_arcsec: float = Field(1.0, ge=0)
    wobble_period_s: float = Field(60.0, gt=0)
    wobble_coherence_s: float = Field(600.0, gt=0)

    # ----- derived magnitudes (radians, g) -----
    @property
    def resolver_coefficient_sigmas(self) -> tuple[float, float, float, float]:
        """Std of the sin/cos coefficients of the first and second harmonics, rad.

        A harmonic a sin(p + f) with f uniform has sin p and cos p coefficients of variance
        a^2/2 each, uncorrelated.
        """
        a = self.resolver_cyclic_arcsec * ARCSEC
        s1, s2 = (h * a / math.sqrt(2.0) for h in self.resolver_harmonics)
        return (s1, s1, s2, s2)

    @property
    def bubble_sigma(self) -> float:
        """One level reading's error, rad: noise plus graduation (uniform, q^2/12)."""
        q = self.bubble_graduation_arcsec
        return math.sqrt(self.bubble_noise_arcsec**2 + q * q / 12.0) * ARCSEC

    def tilt_covariance(self, lag: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(east-east, north-north, east-north) tilt covariance at a lag (s), rad^2."""
        tau = np.abs(np.asarray(lag, dtype=float))
        amp = 0.5 * self.tilt_diurnal_pp_arcsec * ARCSEC
        az = math.radians(self.tilt_diurnal_azimuth_deg)
        diurnal = 0.5 * amp * amp * np.cos(2 * math.pi * tau / DAY)
        wander = (self.tilt_wander_sigma_arcsec * ARCSEC) ** 2 * np.exp(
            -tau / self.tilt_wander_tau_s
        )
        b = self.wobble_amplitude_arcsec * ARCSEC
        wobble = (
            0.5
            * b
            * b
            * np.cos(2 * math.pi * tau / self.wobble_period_s)
            * np.sinc(tau / self.wobble_coherence_s)
        )
        ee = diurnal * math.cos(az) ** 2 + wander + wobble
        nn = diurnal * math.sin(az) ** 2 + wander + wobble
        en = diurnal * math.cos(az) * math.sin(az)
        return ee, nn, en
