"""Configuration of the CIGTF station: a TOML file with a ``[cigtf]`` section.

Only the laboratory's scalar settings are exposed (site latitude, misalignment and noise
magnitudes, slew rate, averaging time); a bad field is refused with a message naming it.

Near a pole the gyrocompass test means nothing, and the latitude is refused with the
reason. The test turns the fixture 1 deg to find its scale factor (report 001, eq. 14:
GSF = 900 / dI arcsec per mA, dI = Omega cos(lat) sin(1 deg) / S_T), dI being the
difference of two means of n averages: the GSF carries a relative error
eps = sigma_I sqrt(2/n) / dI. Every run's theta is scaled by that one GSF, and theta holds
the level error's coupling b tan(lat) (eq. 26; b taken at 3 level sd). The bias
eps b tan(lat) must stay under the sigma of the operating phase's mean,
GSF sigma_I sqrt(4/n) / sqrt(N). The noise, n and S_T cancel:
tan(lat) <= sin(1 deg) / (2 sqrt(2 N) b) = 254.6 arcsec / b for N = 25 runs, i.e.
87.98 deg for the default level sd of 3 arcsec (b = 9 arcsec). The GSF must also be found
at all: eps <= 10 %, which bounds sigma_I by 0.059 cos(lat) mA (0.049 mA at the report's
site, 25 times the default).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

from pydantic import BaseModel, Field, ValidationInfo, field_validator

from sim.cigtf.world import MA, CigtfParams
from sim.units import ARCSEC, EARTH_RATE
from station.config.file import read_section
from station.config.limits import CigtfLimits
from station.config.strict import STRICT

# The test plan's figures (procedures.cigtf.procedure.TestPlan; a test checks
# they agree): averages per orientation, operating runs, the GSF turn.
SAMPLES = 10
OPERATING_RUNS = 25
TURN_DEG = 1.0
LEVEL_SIGMAS = 3.0  # the level error b taken at 3 of its standard deviations
GSF_REL_ERROR_MAX = 0.1
LATITUDE_MAX_DEG = 89.0  # whatever the noise: cos(lat) is 0.017 there


def max_tan_latitude(level_sd_arcsec: float) -> float:
    """tan of the highest latitude where the GSF's error biases theta less than the
    operating phase's sigma (module docstring); inf without a level error."""
    b = LEVEL_SIGMAS * level_sd_arcsec * ARCSEC  # rad
    if b == 0.0:
        return math.inf
    return math.sin(math.radians(TURN_DEG)) / (2.0 * math.sqrt(2.0 * OPERATING_RUNS) * b)


def turn_current_ma(latitude_deg: float, s_t: float) -> float:
    """dI of the GSF turn, mA (S_T in rad/s per A)."""
    return (EARTH_RATE * math.cos(math.radians(latitude_deg))
            * math.sin(math.radians(TURN_DEG)) / s_t / MA)


def max_current_noise_ma(latitude_deg: float, s_t: float) -> float:
    """The DVM noise at which the GSF turn finds the scale factor to GSF_REL_ERROR_MAX."""
    return GSF_REL_ERROR_MAX * turn_current_ma(latitude_deg, s_t) / math.sqrt(2.0 / SAMPLES)


_DEFAULTS = CigtfParams()


class Eq27Config(BaseModel):
    """``[cigtf.eq27]``: the eq. 27 correction of report 001 (Appendix II) and the values
    the laboratory has for it, each with its 1-sigma error: the bubble levels' b and c
    (arcsec), the gyro's calibrated D_I and D_OS (deg/hr per g), the error of the fixture's
    180 deg vertical null (arcsec). ``apply`` (or ``--eq27``) corrects each phase's theta."""

    model_config = STRICT
    apply: bool = False
    b_arcsec: float = Field(0.0, ge=-600, le=600)
    c_arcsec: float = Field(0.0, ge=-600, le=600)
    level_sigma_arcsec: float = Field(0.5, ge=0, le=60)
    d_i_deg_hr: float = Field(0.0, ge=-100, le=100)
    d_os_deg_hr: float = Field(0.0, ge=-100, le=100)
    drift_sigma_deg_hr: float = Field(0.0, ge=0, le=100)
    v180_error_arcsec: float = Field(0.0, ge=-60, le=60)
    null_sigma_arcsec: float = Field(0.5 / 3.0, ge=0, le=60)  # the fixture's 0.5 sec at 3 sigma


class CigtfConfig(BaseModel):
    # Field order matters: the latitude is checked against the level error, then the
    # noise against the latitude (each error names the field that is out of bounds).
    model_config = STRICT
    level_sd_arcsec: float | None = Field(None, ge=0, le=60)  # a, b, c: a levelled fixture
    perpendicular_sd_arcsec: float | None = Field(None, ge=0, le=60)  # d, e, f
    mount_sd_arcsec: float | None = Field(None, ge=0, le=600)  # h, i, j: first-order models
    # 180 deg turns must hold within the procedure's 120 s wait: 2 deg/s at least.
    slew_deg_s: float | None = Field(None, ge=2.0, le=60.0)
    # The test waits 10 s plus the DVM driver's 5-s reply timeout for each average (it
    # does not ask APER?): a longer aperture is a certain LinkTimeout in step 4.1.1.
    average_s: float | None = Field(None, ge=1.0, le=14.0)
    latitude_deg: float | None = Field(None, ge=-LATITUDE_MAX_DEG, le=LATITUDE_MAX_DEG,
                                       validate_default=True)
    # at most 0.059 cos(lat) mA (module docstring): never more than 0.06
    current_noise_ma: float | None = Field(None, ge=0, le=0.06, validate_default=True)

    @field_validator("latitude_deg")
    @classmethod
    def _gyrocompass_is_meaningful(cls, v: float | None, info: ValidationInfo
                                   ) -> float | None:
        lat = _DEFAULTS.latitude_deg if v is None else v
        level = info.data.get("level_sd_arcsec")
        level = _DEFAULTS.level_sd_arcsec if level is None else level
        limit = math.degrees(math.atan(max_tan_latitude(level)))
        if abs(lat) > limit:
            raise ValueError(
                f"{lat:g} deg is too near the pole for the gyrocompass test: the 1 deg turn "
                f"fixes the scale factor (eq. 14) too loosely against the level error's "
                f"b tan(lat) coupling, biasing theta beyond its sigma; with level_sd_arcsec "
                f"= {level:g} the limit is +-{limit:.2f} deg")
        return v

    @field_validator("current_noise_ma")
    @classmethod
    def _turn_finds_the_scale_factor(cls, v: float | None, info: ValidationInfo
                                     ) -> float | None:
        if "latitude_deg" not in info.data:  # the latitude was refused already
            return v
        lat = info.data["latitude_deg"]
        lat = _DEFAULTS.latitude_deg if lat is None else lat
        noise = _DEFAULTS.current_noise_ma if v is None else v
        most = max_current_noise_ma(lat, _DEFAULTS.model.s_t)
        if noise > most:
            raise ValueError(
                f"{noise:g} mA is too much noise for the 1 deg turn to find the scale "
                f"factor (eq. 14) at latitude {lat:.4g} deg: at most {most:.3g} mA there "
                f"({GSF_REL_ERROR_MAX:.0%} of the turn's current change)")
        return v

    # the section 4.1 set-up levels and aligns the fixture (a, b, c are what it leaves);
    # false: a, b, c drawn at level_sd_arcsec and no set-up (the test before the set-up)
    pretest_setup: bool | None = None
    # the spin motor's excitation (V) and the magnetic drift it drives (deg/hr per gauss
    # along I at the nominal 26 V): section 1's rotor-voltage variation
    rotor_voltage_v: float | None = Field(None, ge=10.0, le=40.0)
    magnetic_drift_deg_hr_per_gauss: float | None = Field(None, ge=-1.0, le=1.0)
    limits: CigtfLimits = CigtfLimits()  # acceptance limits (station/config/limits.py)
    eq27: Eq27Config = Eq27Config()  # the eq. 27 correction's values (laboratory side)


def load_cigtf_params(path: str | Path | None) -> CigtfParams:
    """The default CigtfParams with the file's [cigtf] settings applied."""
    if path is None:
        return CigtfParams()
    return params_from(read_section(path, "cigtf", CigtfConfig, "CIGTF"))


def params_from(cfg: CigtfConfig) -> CigtfParams:
    """The default CigtfParams with the settings ``cfg`` gives (its limits and eq. 27
    values are the laboratory's, not the simulation's)."""
    dumped = cfg.model_dump(exclude={"limits", "eq27"})
    return replace(CigtfParams(), **{k: v for k, v in dumped.items() if v is not None})


def load_cigtf_limits(path: str | Path | None) -> CigtfLimits:
    """The ``[cigtf.limits]`` of a CIGTF file (defaults without one)."""
    if path is None:
        return CigtfLimits()
    return read_section(path, "cigtf", CigtfConfig, "CIGTF").limits


def load_cigtf_eq27(path: str | Path | None) -> Eq27Config:
    """The ``[cigtf.eq27]`` of a CIGTF file (not applied, zero values, without one)."""
    if path is None:
        return Eq27Config()
    return read_section(path, "cigtf", CigtfConfig, "CIGTF").eq27
