"""The ISU calibration laboratory's sheets (report 000: Charts I-3, II-1..II-5, II-17, II-20)
as data. Lab units at this boundary: degrees, arcsec, deg/hr, g, pulses, counts.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np
from pydantic import Field

from procedures.sheets import CheckSheet, Sheet, SheetHeader


class SurveyResults(Sheet):
    """Survey Results Sheet (Chart I-3)."""

    g: float  # local gravity, in g (standard gravity units)
    omega_sin_lambda_deg_hr: float  # north component of Earth rate
    omega_cos_lambda_deg_hr: float  # vertical component of Earth rate
    position0_deg: tuple[float, float, float, float]  # phi1..phi4 at position 0
    autocollimator_deg: tuple[float, float, float, float]  # alpha1, theta1, alpha2, theta2
    t_bi: list[list[float]]
    settings_deg: dict[str, tuple[float, float]]  # m -> (phi3^m, phi4^m), m = 1, 3, 5, 13, 14, 15
    t_br_column2: dict[str, tuple[float, float, float]]  # m -> (T12, T22, T32)^BRm
    # Chart I-6 step 4: m -> (T13, T23, T33)^BRm, for information (no equation uses it)
    t_br_column3: dict[str, tuple[float, float, float]] = Field(default_factory=dict)
    header: SheetHeader | None = None


class PositionSetting(Sheet):
    phi1: float
    phi2: float | None  # None: rotating
    phi3: float
    phi4: float
    bubble_correction: bool


class ResolverSettings(Sheet):
    """Test Table Resolver Settings Sheet (Chart II-1 / II-17), degrees."""

    positions: dict[str, PositionSetting]
    header: SheetHeader | None = None


class CounterConnection(Sheet):
    xy: str  # e.g. "G1+/G1-", "A1S1", "OSC1"
    z: str
    mode: str  # "measure Z" | "measure X-Y"


class CounterConnections(Sheet):
    """Counter Connections Sheet (Chart II-2): experiment -> counter -> patching."""

    experiments: dict[str, dict[str, CounterConnection]]
    header: SheetHeader | None = None


class GateSetting(Sheet):
    """One collection time of II-6.2: the requirement it serves, the predicted sigma at the
    chosen time (covariance model), the manual's default and why the time is what it is."""

    requirement: str
    required: float
    predicted: float
    units: str  # of the times: "turns" or "s"
    default: float
    chosen: float
    why: str


class CounterSettings(Sheet):
    """Counter Settings Sheet (Chart II-3 / II-20): position -> counter -> preset."""

    presets: dict[str, dict[str, int]]
    basis: dict[str, str]  # experiment -> how the preset follows from the required accuracy
    gates: dict[str, GateSetting] = Field(default_factory=dict)  # gate -> II-6.2 choice
    header: SheetHeader | None = None


class CounterOutputs(Sheet):
    """Counter Outputs Sheet (Chart II-4): position -> counter -> reading."""

    outputs: dict[str, dict[str, int]] = Field(default_factory=dict)
    header: SheetHeader | None = None


class NonlinearityGate(Sheet):
    """One speed of a gyro's nonlinearity series: the counters, their preset and the speed."""

    counters: tuple[int, int]  # counter 1 (S1^T ticks) and counter k + 1 (gyro k pulses)
    preset: int  # (Sigma n^phi): rotary-axis pulses, whole turns
    rate_deg_s: float  # the table speed to set


class NonlinearityCounterSettings(Sheet):
    """Counter Settings Sheet for the nonlinearity experiments (Chart II-8): gyro -> speed
    (deg/s, signed) -> its gate. The report does not print the form; these are the settings
    Chart II-7 steps 6 and 7 take from it."""

    gyros: dict[str, dict[str, NonlinearityGate]]
    header: SheetHeader | None = None


class NonlinearityOutput(Sheet):
    """One speed's counter outputs (Chart II-7 step 10) and steps 14-15's rates."""

    ticks: int  # counter 1: S1^T periods over the whole turns
    counts: int  # counter k + 1: gyro pulses over the same turns
    w_deg_hr: float  # step 14: total rate about the rotary axis
    p_dot: float  # step 15: output frequency, pulses/s


class NonlinearityCounterOutputs(Sheet):
    """Counter Outputs Sheet for the nonlinearity experiments (Chart II-9): gyro -> speed
    -> outputs (the report does not print the form: designed from Chart II-7)."""

    gyros: dict[str, dict[str, NonlinearityOutput]] = Field(default_factory=dict)
    header: SheetHeader | None = None


ARCSEC_PER_DEG = 3600.0
F = TypeVar("F", float, np.ndarray)


def scale_factor_arcsec(deg_per_pulse: F) -> F:
    """A gyro scale factor as the sheet records it (Chart II-5 prints DeltaPhi in
    deg/pulse) in the arcsec/pulse the count-noise and drift figures of II-6.2 use."""
    return deg_per_pulse * ARCSEC_PER_DEG


class ResultRow(Sheet):
    instrument: str  # gyro1..gyro3, accel1..accel3
    parameter: str  # as on Chart II-5: DeltaPhi, G.B1, R, ..., D1, A.B1, D0, D2, D3
    units: str
    estimate: float | None
    sigma: float | None
    positions: str  # Chart II-16 entry (prerequisites in parentheses)
    note: str = ""
    # issue 19: both estimators side by side; estimate/sigma are the ``estimator``'s
    estimator: str = "closed-form"
    closed_form: float | None = None
    closed_form_sigma: float | None = None
    all_positions: float | None = None
    all_positions_sigma: float | None = None
    cramer_rao_sigma: float | None = None  # the day's design's bound, at the estimate


class ConstantsCorrelation(Sheet):
    """Correlation of the constants computed together from one day's data (Chart II-15
    step 8): the closed forms share readings, so e.g. D0 and A.B of a horizontal
    accelerometer correlate; the alignment's error model needs it (with the rows' sigmas)."""

    rows: list[str]  # "accel1 D0", in the order of the matrix
    matrix: list[list[float]]  # symmetric, unit diagonal, four decimals


class CalibrationResults(Sheet):
    """Calibration Results Sheet (Chart II-5)."""

    rows: list[ResultRow]
    positions_used: list[int]
    header: SheetHeader | None = None
    correlation: ConstantsCorrelation | None = None  # None: constants taken as independent


# The chart each sheet is, and the sheets its heading cites as used ("Survey Results Sheet
# Used ..." on Chart II-5; Chart III-1 names the calibration constants it used). A check-sheet
# check_<chart> is its chart's procedure.
SHEET_CHARTS = {"survey_results": "I-3", "resolver_settings": "II-1",
                "counter_connections": "II-2", "counter_settings": "II-3",
                "counter_outputs": "II-4", "calibration_results": "II-5",
                "nonlinearity_counter_settings": "II-8",
                "nonlinearity_counter_outputs": "II-9"}
SHEETS_USED: dict[str, list[str]] = {
    "I-3": [],
    "II-1": ["Chart I-3"],
    "II-2": [],
    "II-3": ["Chart II-2"],
    "II-4": ["Chart II-2", "Chart II-3"],
    "II-5": ["Chart I-3", "Chart II-1", "Chart II-3", "Chart II-4"],
    "II-7": ["Chart II-1", "Chart II-8", "Chart II-9"],
    "II-8": ["Chart II-1"],
    "II-9": ["Chart I-3", "Chart II-8"],
    "III-1": ["Chart I-3", "Chart II-5"],
}


ISU_SHEETS: dict[str, type[Sheet]] = {
    "check": CheckSheet,  # every check_<chart> sheet
    "survey_results": SurveyResults,
    "resolver_settings": ResolverSettings,
    "counter_connections": CounterConnections,
    "counter_settings": CounterSettings,
    "counter_outputs": CounterOutputs,
    "calibration_results": CalibrationResults,
    "nonlinearity_counter_settings": NonlinearityCounterSettings,
    "nonlinearity_counter_outputs": NonlinearityCounterOutputs,
}


def sheets_used(name: str) -> list[str]:
    """The "Sheet Used" cross-references of the sheet ``name`` (Charts I-3, II-2..II-5,
    III-1); a check-sheet ``check_<chart>`` cites what its chart's results sheet does."""
    if name.startswith("alignment_results"):
        chart = "III-1"
    elif name.startswith("check_"):
        chart = name.removeprefix("check_")
    else:
        chart = SHEET_CHARTS.get(name, "")
    return list(SHEETS_USED.get(chart, []))
