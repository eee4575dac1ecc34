"""Calibration computations of report 000 (Part II, Section 4: Charts II-15 and II-16).

``calibrate(data, noise)`` turns the counter data of positions 1-15 (full or partial) into
the rows of the Calibration Results Sheet (Chart II-5): estimate, predicted standard error
and the Chart II-16 positions of every gyro and accelerometer constant.

Modules: ``inputs`` (data types), ``noise_spec`` (the lab's specifications), ``reduce``
(counts to rates), ``gyro_equations`` / ``accel_equations`` (closed forms of II-4.2 and
II-4.3), ``chart_ii16`` (which positions each constant needs), ``geometry`` (positions and
table error map), ``forward`` (expected rates), ``kernels`` and ``covariance`` (error model),
``compute`` (estimates, error propagation, result rows).
"""

from procedures.isu.calibration.compute import calibrate, estimate, predicted_sigmas
from procedures.isu.calibration.inputs import (
    AccelPosition,
    CalibrationData,
    Constants,
    GyroPosition,
    TableGeometry,
)
from procedures.isu.calibration.noise_spec import NoiseSpec

__all__ = [
    "AccelPosition",
    "CalibrationData",
    "Constants",
    "GyroPosition",
    "NoiseSpec",
    "TableGeometry",
    "calibrate",
    "estimate",
    "predicted_sigmas",
]
